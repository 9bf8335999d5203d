"""Paper, Fig. "control": the cartpole from hanging to upright at the origin. The LTV
approach (D2C) starts from a random trajectory; SINDy and MLP models trained on data
around its optimum (two levels, two seeds) are then used for iLQR, and every controller is
executed on the black box."""

from mjx_surrogate.config import (
    Config,
    DataConfig,
    ExperimentConfig,
    MLPConfig,
    SindyConfig,
    SolverConfig,
    SurrogateConfig,
    SystemConfig,
    TaskConfig,
)

CONFIG = Config(
    system=SystemConfig(name="cartpole"),
    task=TaskConfig(preset="cartpole_upright"),
    solver=SolverConfig(
        sysid="central_difference", n_samples=25, init="random", init_scale=0.1, max_iter=300, rel_tol=1e-6
    ),
    experiment=ExperimentConfig(kind="control", x64=True),
    data=DataConfig(n_traj=2000, levels=(0.05, 0.25), n_seeds=2),
    surrogate=SurrogateConfig(
        sindy=SindyConfig(libraries=("cubic_trig", "quartic")), mlp=MLPConfig(epochs=200)
    ),
)
