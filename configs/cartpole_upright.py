"""Paper: cartpole from hanging to upright at the origin, from a random trajectory."""

from mjx_surrogate.runs.config import Config, ExperimentConfig, SolverConfig, SystemConfig, TaskConfig

CONFIG = Config(
    system=SystemConfig(name="cartpole"),
    task=TaskConfig(preset="cartpole_upright"),
    solver=SolverConfig(
        sysid="central_difference", n_samples=25, init="random", init_scale=0.1, max_iter=300, rel_tol=1e-6
    ),
    experiment=ExperimentConfig(kind="d2c"),
)
