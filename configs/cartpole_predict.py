"""Paper, Fig. LTV_Cartpole: cartpole swing-up (pole 180 -> 60 deg in 30 steps); 2000
perturbed trajectories per level, split 9 : 1, 5 such data sets per level (the claim is
judged on each); SINDy, MLP and LTV predictions. The MLP
trains to the minimum of a validation set (a tenth of the training trajectories, patience
20 epochs, at most 3000); the paper's fixed 200 epochs on all training data are fitted
beside it ("MLP 200 epochs", the same initialisation)."""

from configs import preset

CONFIG = preset(
    system={"name": "cartpole"},
    task={"preset": "cartpole_swingup"},
    solver={"max_iter": 300, "rel_tol": 1e-6, "init": "zeros"},
    sysid={"n_samples": 25},
    experiment={"kind": "predict", "x64": True},
    data={"n_traj": 2000, "levels": (0.05, 0.10, 0.15, 0.25, 0.30, 0.60, 1.00), "n_seeds": 5},
    surrogate={
        "sindy.libraries": ("cubic_trig", "quartic", "quartic_trig"),
        "mlp.epochs": 3000,
        "mlp.patience": 20,
        "mlp.fixed_epochs_beside": 200,
    },
)
