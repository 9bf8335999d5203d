"""Paper, "Sampling distributions" (Fig. LTV): pendulum swing-up 180 -> 60 deg in 30 steps;
2000 perturbed trajectories per level, split 9 : 1; SINDy, MLP and LTV predictions."""

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
    system=SystemConfig(name="pendulum"),
    task=TaskConfig(preset="pendulum_swingup"),
    solver=SolverConfig(n_samples=10, max_iter=100, rel_tol=1e-6, init="zeros"),
    experiment=ExperimentConfig(kind="predict", x64=True),
    data=DataConfig(n_traj=2000, levels=(0.05, 0.10, 0.15, 0.25, 0.30, 0.60, 1.00)),
    surrogate=SurrogateConfig(
        sindy=SindyConfig(libraries=("cubic_trig", "quartic", "quartic_trig")), mlp=MLPConfig(epochs=200)
    ),
)
