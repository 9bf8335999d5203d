"""The embedded default: D2C swing-up of the pendulum against the exact oracle (~1 min)."""

from mjx_surrogate.config import Config, ExperimentConfig, SolverConfig, SystemConfig, TaskConfig

CONFIG = Config(
    system=SystemConfig(name="pendulum"),
    task=TaskConfig(preset="pendulum_d2c"),
    solver=SolverConfig(sysid="central_difference", max_iter=100, rel_tol=1e-5),
    experiment=ExperimentConfig(kind="d2c"),
)
