"""The paper's prediction study on the F-8 model of SINDy-MPC: D2C optimum of
``f8_recovery``, perturbed data sets per level, SINDy (polynomials up to degree 3, the
model's own degree), MLP and LTV open-loop predictions."""

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
    system=SystemConfig(name="f8"),
    task=TaskConfig(preset="f8_recovery"),
    solver=SolverConfig(max_iter=300),
    experiment=ExperimentConfig(kind="predict"),
    data=DataConfig(n_traj=500, levels=(0.05, 0.10, 0.30, 0.60, 1.00)),
    surrogate=SurrogateConfig(sindy=SindyConfig(libraries=("poly2", "poly3")), mlp=MLPConfig(epochs=100)),
)
