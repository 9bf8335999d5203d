"""The F-8 Crusader's longitudinal model of SINDy-MPC (``mjx_surrogate.systems.f8``): D2C
recovery from a 26.7 deg angle of attack against the jacfwd oracle; the solver's
defaults, up to 300 iterations."""

from mjx_surrogate.runs.config import Config, ExperimentConfig, SolverConfig, SystemConfig, TaskConfig

CONFIG = Config(
    system=SystemConfig(name="f8"),
    task=TaskConfig(preset="f8_recovery"),
    solver=SolverConfig(max_iter=300),
    experiment=ExperimentConfig(kind="d2c"),
)
