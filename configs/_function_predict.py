"""The prediction study on a function black box of SINDy-MPC (shared by ``lorenz_predict``
and ``f8_predict``): D2C optimum of the task preset, 500 perturbed trajectories per level,
SINDy with polynomials up to degree 3 (both systems' own terms are polynomials of degree
at most 3), MLP and LTV open-loop predictions."""

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


def predict_config(system: str, task_preset: str) -> Config:
    return Config(
        system=SystemConfig(name=system),
        task=TaskConfig(preset=task_preset),
        solver=SolverConfig(max_iter=300),
        experiment=ExperimentConfig(kind="predict"),
        data=DataConfig(n_traj=500, levels=(0.05, 0.10, 0.30, 0.60, 1.00)),
        surrogate=SurrogateConfig(sindy=SindyConfig(libraries=("poly2", "poly3")), mlp=MLPConfig(epochs=100)),
    )
