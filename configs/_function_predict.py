"""The prediction study on a function black box of SINDy-MPC (shared by ``lorenz_predict``
and ``f8_predict``): D2C optimum of the task preset, 500 perturbed trajectories per level,
SINDy with polynomials up to degree 3 (both systems' own terms are polynomials of degree
at most 3), MLP and LTV open-loop predictions."""

from configs import preset
from mjx_surrogate.runs.config import Config


def predict_config(system: str, task_preset: str) -> Config:
    return preset(
        system={"name": system},
        task={"preset": task_preset},
        solver={"max_iter": 300},
        experiment={"kind": "predict"},
        data={"n_traj": 500, "levels": (0.05, 0.10, 0.30, 0.60, 1.00)},
        surrogate={"sindy.libraries": ("poly2", "poly3"), "mlp.epochs": 100},
    )
