"""Control with the surrogates on the fish (the paper's control study, on a 3-D swimmer):
rest -> target, T 600, from random controls. D2C finds the optimum; SINDy (quadratic) and
MLP models trained on 200 perturbed trajectories at 5 % U_max around it (the fish
prediction preset's sizes; 5 data sets, the MLPs trained at once along a leading axis)
drive iLQR from the same start, and every controller runs on the black box. The exact
oracle (MJX jacfwd through 600 steps of a contact-free 3-D body) is left to a GPU:
--experiment.exact_oracle.

From this start (seed 0) D2C crosses a long valley, each iteration gaining 2-4e-5 of the
cost at the smallest regularisation: it converges after 602-632 iterations at 566.14
(570.31 after 300, the prediction preset's cap), so the cap here is 800."""

import dataclasses

from configs.fish_predict import CONFIG as _PREDICT  # the same system, task and solver
from mjx_surrogate.runs.config import DataConfig, ExperimentConfig, MLPConfig, SindyConfig, SurrogateConfig

CONFIG = dataclasses.replace(
    _PREDICT,
    solver=dataclasses.replace(_PREDICT.solver, max_iter=800),
    experiment=ExperimentConfig(kind="control", exact_oracle=False, x64=True),
    data=DataConfig(n_traj=200, levels=(0.05,), n_seeds=5),
    surrogate=SurrogateConfig(
        sindy=SindyConfig(libraries=("poly2",)), mlp=MLPConfig(epochs=1000, patience=20)
    ),
)
