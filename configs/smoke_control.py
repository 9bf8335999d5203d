"""CI smoke: control with surrogates on the pendulum, tiny sizes."""

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
    solver=SolverConfig(n_samples=6, max_iter=30, init="random"),
    experiment=ExperimentConfig(kind="control", progress=False, video=False, x64=True),
    data=DataConfig(n_traj=40, levels=(0.1,)),
    surrogate=SurrogateConfig(
        sindy=SindyConfig(libraries=("cubic_trig",)), mlp=MLPConfig(epochs=3, batch_size=32)
    ),
)
