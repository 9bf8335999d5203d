"""Paper, Fig. "control": the cartpole from hanging to upright at the origin. The LTV
approach (D2C) starts from a random trajectory; SINDy and MLP models trained on data
around its optimum (two levels, five seeds: data sets and initialisations, the MLPs trained
at once along a leading axis) are then used for iLQR, and every controller is executed on
the black box. D2C and the exact oracle also run from 5 more random starts, each D2C solve
judged against the oracle's from the same start."""

import dataclasses

from configs import derive

CONFIG = derive(
    "cartpole_predict",
    task={"preset": "cartpole_upright"},
    solver={"init": "random", "init_scale": 0.1},
    sysid={"scheme": "central_difference"},
    experiment={"kind": "control"},
    data={"levels": (0.05, 0.25), "n_seeds": 5},
    # the MLP to its validation minimum (cartpole_predict's); the fixed-epoch one is left to
    # the prediction study
    surrogate={"sindy.libraries": ("cubic_trig", "quartic"), "mlp.fixed_epochs_beside": 0},
)
CONFIG = dataclasses.replace(CONFIG, extensions={**CONFIG.extensions, "experiment.control": {"starts": 5}})
