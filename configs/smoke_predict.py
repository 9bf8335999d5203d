"""CI smoke: the prediction experiment on the pendulum, tiny sizes."""

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
    system=SystemConfig(name="pendulum", backend="native"),  # compiles in seconds
    task=TaskConfig(preset="pendulum_swingup", T=10),
    solver=SolverConfig(n_samples=6, max_iter=30, init="zeros"),
    experiment=ExperimentConfig(kind="predict", progress=False, video=False, x64=True),
    data=DataConfig(n_traj=40, levels=(0.1, 0.6)),
    surrogate=SurrogateConfig(
        sindy=SindyConfig(libraries=("cubic_trig", "quartic")), mlp=MLPConfig(epochs=5, batch_size=64)
    ),
)
