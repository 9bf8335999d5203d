"""Paper, Fig. LTV_Cartpole: cartpole swing-up (pole 180 -> 60 deg in 30 steps); 2000
perturbed trajectories per level, split 9 : 1; SINDy, MLP and LTV predictions."""

from configs import preset

CONFIG = preset(
    system={"name": "cartpole"},
    task={"preset": "cartpole_swingup"},
    solver={"n_samples": 25, "max_iter": 300, "rel_tol": 1e-6, "init": "zeros"},
    experiment={"kind": "predict", "x64": True},
    data={"n_traj": 2000, "levels": (0.05, 0.10, 0.15, 0.25, 0.30, 0.60, 1.00)},
    surrogate={"sindy.libraries": ("cubic_trig", "quartic", "quartic_trig"), "mlp.epochs": 200},
)
