"""Control with the surrogates on the pendulum (the paper's control study, on its second
system): from random controls to upright (D2C 2.0's pendulum task). D2C finds the optimum
with local LTV models; SINDy and MLP models trained on data around that optimum (two
levels, five seeds) drive iLQR from the same start, and every controller runs on the black box;
D2C and the oracle also from 5 more random starts, each judged against the other."""

import dataclasses

from configs.cartpole_control import CONFIG as _CARTPOLE  # the same study: data, surrogates
from mjx_surrogate.runs.config import SolverConfig, SysIdConfig, SystemConfig, TaskConfig

CONFIG = dataclasses.replace(
    _CARTPOLE,
    system=SystemConfig(name="pendulum"),
    task=TaskConfig(preset="pendulum_d2c"),
    solver=SolverConfig(init="random", init_scale=0.1, max_iter=100, rel_tol=1e-6),
    sysid=SysIdConfig(scheme="central_difference", n_samples=10),
)
