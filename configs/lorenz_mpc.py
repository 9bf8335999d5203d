"""Closed loop on SINDy-MPC's own benchmark, its published task and data budget (Kaiser,
Kutz, Brunton 2018; the authors' code, EX_LORENZ): the Lorenz system steered from
(-8, 8, 27) to the fixed point C- over 5 time units (500 steps of 0.01), every controller
replanning over a horizon of 10 steps under process noise. The surrogates get that
paper's training length, 10 time units: 2 training trajectories of 500 steps (and one
for testing) around the offline optimum; SINDy with the system's polynomial terms
(degree 2 and 3) and an MLP. Besides the model, the plant Lorenz with sigma = 13 instead
of 10 (the fixed points stay where they are; the flow between them is faster)."""

import dataclasses

from configs import preset
from configs.gym_inverted_pendulum_mpc import CONTROL_UNITS

CONFIG = preset(
    system={"name": "lorenz"},
    task={"preset": "lorenz_stabilize"},
    solver={"max_iter": 300},
    experiment={"kind": "mpc"},
    data={"n_traj": 3, "test_fraction": 1 / 3},
    surrogate={"sindy.libraries": ("poly2", "poly3"), "mlp.epochs": 100},
    mpc={
        "horizon": 10,
        "horizon_end": "receding",  # SINDy-MPC's loop: every plan 10 steps ahead
        "steps": 500,
        "process_noise": (0.0, 0.1, 0.5),
        "plants": ("model", "sigma=13"),
    },
)
# the sampling planners in control units (|u| <= 50) at their own settings searched on this
# task (docs/mpc.md), each beside its row at D2C-MPC's budget
_OWN = {"samples": 256, "sigma": 20.0, "budget_row": True}
CONFIG = dataclasses.replace(
    CONFIG,
    extensions={
        "mpc.predictive_sampling": {**CONTROL_UNITS["mpc.predictive_sampling"], **_OWN},
        "mpc.mppi": {**CONTROL_UNITS["mpc.mppi"], **_OWN},
        "mpc.cem": {**CONTROL_UNITS["mpc.cem"], **_OWN, "elites": 16, "iterations": 2},
    },
)
