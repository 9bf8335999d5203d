"""Control with the surrogates on the pendulum (the paper's control study, on its second
system): from random controls to upright (D2C 2.0's pendulum task). D2C finds the optimum
with local LTV models; SINDy and MLP models trained on data around that optimum (two
levels, two seeds) drive iLQR from the same start, and every controller runs on the black box."""

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
    task=TaskConfig(preset="pendulum_d2c"),
    solver=SolverConfig(
        sysid="central_difference", n_samples=10, init="random", init_scale=0.1, max_iter=100, rel_tol=1e-6
    ),
    experiment=ExperimentConfig(kind="control", x64=True),
    data=DataConfig(n_traj=2000, levels=(0.05, 0.25), n_seeds=2),
    surrogate=SurrogateConfig(
        sindy=SindyConfig(libraries=("cubic_trig", "quartic")), mlp=MLPConfig(epochs=200)
    ),
)
