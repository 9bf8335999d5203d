"""CI smoke: the analysis experiment on the pendulum, tiny sizes."""

from mjx_surrogate.config import (
    AnalysisConfig,
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
    experiment=ExperimentConfig(kind="analysis", progress=False, video=False, x64=True),
    data=DataConfig(n_traj=30),
    surrogate=SurrogateConfig(
        sindy=SindyConfig(libraries=("cubic_trig",)), mlp=MLPConfig(epochs=3, batch_size=32)
    ),
    analysis=AnalysisConfig(
        n_datasets=3,
        gram_points=100,
        convergence_sindy_levels=(0.1,),
        convergence_mlp_levels=(0.05,),
        gram_mlp_levels=(0.05,),
    ),
)
