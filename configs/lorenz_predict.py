"""The paper's prediction study on SINDy-MPC's Lorenz system: D2C optimum of
``lorenz_switch``, perturbed data sets per level, SINDy (polynomials up to degree 3, the
Lorenz system's own terms are degree 2), MLP and LTV open-loop predictions."""

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
    system=SystemConfig(name="lorenz"),
    task=TaskConfig(preset="lorenz_switch"),
    solver=SolverConfig(max_iter=300),
    experiment=ExperimentConfig(kind="predict"),
    data=DataConfig(n_traj=500, levels=(0.05, 0.10, 0.30, 0.60, 1.00)),
    surrogate=SurrogateConfig(sindy=SindyConfig(libraries=("poly2", "poly3")), mlp=MLPConfig(epochs=100)),
)
