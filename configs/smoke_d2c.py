"""CI smoke: D2C on the pendulum over 10 steps against the finite-difference oracle, on the
native backend (its programs compile in seconds)."""

from mjx_surrogate.runs.config import (
    Config,
    ExperimentConfig,
    SolverConfig,
    SysIdConfig,
    SystemConfig,
    TaskConfig,
)

CONFIG = Config(
    system=SystemConfig(name="pendulum", backend="native"),
    task=TaskConfig(preset="pendulum_d2c", T=10),
    solver=SolverConfig(max_iter=30, init="random"),
    sysid=SysIdConfig(n_samples=6),
    experiment=ExperimentConfig(
        kind="d2c", n_noise_trials=8, progress=False, video=False, oracle="finite_difference"
    ),
)
