"""Beyond the paper: identification error against the horizon on the cartpole swing-up
(the prediction preset's task and optimum). 500 rollouts per level, open loop and under the
optimum's gains, identified per step; reference Jacobians by central differences."""

from configs import derive

CONFIG = derive(
    "cartpole_predict",
    experiment={"kind": "horizon", "oracle": "finite_difference"},
    data={"n_traj": 500, "levels": (0.01, 0.05, 0.25)},
)
