"""CI smoke: the analysis experiment on the pendulum, tiny sizes."""

from configs import derive
from mjx_surrogate.runs.config import DataConfig

CONFIG = derive(
    "smoke_control",
    solver={"init": "zeros"},
    experiment={"kind": "analysis"},
    data={"n_traj": 30, "levels": DataConfig().levels},
    analysis={
        "n_datasets": 3,
        "gram_points": 100,
        "convergence_sindy_levels": (0.1,),
        "convergence_mlp_levels": (0.05,),
        "gram_mlp_levels": (0.05,),
    },
)
