"""SINDy-MPC's Lorenz system with control (``mjx_surrogate.systems.lorenz``): D2C from the
fixed point C- to C+ in 2 s against the jacfwd oracle; the solver's defaults, up to 300 iterations."""

from mjx_surrogate.runs.config import Config, ExperimentConfig, SolverConfig, SystemConfig, TaskConfig

CONFIG = Config(
    system=SystemConfig(name="lorenz"),
    task=TaskConfig(preset="lorenz_switch"),
    solver=SolverConfig(max_iter=300),  # the Lorenz switch takes about 110 iterations
    experiment=ExperimentConfig(kind="d2c"),
)
