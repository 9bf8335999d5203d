"""Paper: pendulum swing-up from 180 deg to rest at 60 deg in 30 steps, from zero controls."""

from mjx_surrogate.runs.config import Config, ExperimentConfig, SolverConfig, SystemConfig, TaskConfig

CONFIG = Config(
    system=SystemConfig(name="pendulum"),
    task=TaskConfig(preset="pendulum_swingup"),
    solver=SolverConfig(
        sysid="central_difference", n_samples=10, init="zeros", init_scale=0.1, max_iter=100, rel_tol=1e-6
    ),
    experiment=ExperimentConfig(kind="d2c"),
)
