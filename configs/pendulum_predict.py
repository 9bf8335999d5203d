"""Paper, "Sampling distributions" (Fig. LTV): pendulum swing-up 180 -> 60 deg in 30 steps;
2000 perturbed trajectories per level, split 9 : 1; SINDy, MLP and LTV predictions."""

from configs import derive

CONFIG = derive(  # the cartpole's study, on the pendulum
    "cartpole_predict",
    system={"name": "pendulum"},
    task={"preset": "pendulum_swingup"},
    solver={"max_iter": 100},
    sysid={"n_samples": 10},
)
