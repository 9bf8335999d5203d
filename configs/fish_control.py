"""Control with the surrogates on the fish (the paper's control study, on a 3-D swimmer):
rest -> target, T 600, from random controls. D2C finds the optimum; SINDy (quadratic) and
MLP models trained on 200 perturbed trajectories at 5 % U_max around it (the fish
prediction preset's sizes) drive iLQR from the same start, and every controller runs on the
black box. The exact oracle (MJX jacfwd through 600 steps of a contact-free 3-D body) is
left to a GPU: --experiment.exact_oracle."""

import dataclasses

from configs.fish_predict import CONFIG as _PREDICT  # the same system, task and solver
from mjx_surrogate.config import DataConfig, ExperimentConfig, MLPConfig, SindyConfig, SurrogateConfig

CONFIG = dataclasses.replace(
    _PREDICT,
    experiment=ExperimentConfig(kind="control", exact_oracle=False, x64=True),
    data=DataConfig(n_traj=200, levels=(0.05,), n_seeds=1),
    surrogate=SurrogateConfig(sindy=SindyConfig(libraries=("poly2",)), mlp=MLPConfig(epochs=50)),
)
