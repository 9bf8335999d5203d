"""The paper's prediction study on a PDE (``burgers64``, task ``burgers_damp``): around the
D2C optimum, 5 data sets of 200 perturbed trajectories per level; SINDy with a quadratic
library on the full field (72 coordinates, 2701 features), SINDy on the leading 8 POD modes
(linear and quadratic libraries), the paper's MLP, and the local LTV model, in full order and
in the data's snapshot basis per t; open-loop prediction error against the perturbation
level, the medians over the data sets (docs/pde.md)."""

from configs import preset

CONFIG = preset(
    system={"name": "burgers64"},
    task={"preset": "burgers_damp"},
    experiment={"kind": "predict"},
    data={"n_traj": 200, "levels": (0.05, 0.10, 0.30, 0.60, 1.00), "n_seeds": 5},
    surrogate={
        "kinds": ("sindy", "pod_sindy", "mlp"),
        "reduced_ltv_tol": 1e-8,
        "sindy.libraries": ("poly2",),
        "pod_sindy.rank": 8,
        "pod_sindy.libraries": ("poly1", "poly2"),
        "mlp.epochs": 50,
    },
)
