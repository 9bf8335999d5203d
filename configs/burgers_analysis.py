"""The paper's analyses on a PDE (``burgers32``, task ``burgers_damp``): model convergence
across data sets, Gram-matrix spectra (linear and quadratic libraries, the MLP's parameter
Jacobian) and variance across data sets, around the D2C optimum at 5 % and 60 % of U_max,
100 trajectories, three data sets (docs/pde.md). About 100 s on 2 cores."""

from configs import preset

CONFIG = preset(
    system={"name": "burgers32"},
    task={"preset": "burgers_damp"},
    experiment={"kind": "analysis"},
    data={"n_traj": 100},
    surrogate={"sindy.libraries": ("poly2",), "mlp.epochs": 10},
    analysis={
        "n_datasets": 3,
        "convergence_library": "poly2",
        "convergence_sindy_levels": (0.05, 0.6),
        "convergence_mlp_levels": (0.05, 0.6),
        "gram_sindy_level": 0.05,
        "gram_libraries": ("poly1", "poly2"),
        "gram_mlp_levels": (0.05,),
        "variance_libraries": ("poly1", "poly2"),
        "variance_levels": (0.05, 0.6),
    },
)
