"""hydrax's pendulum swing-up (``hydrax_pendulum``: its model, cost and loop, from the
facts of its task files) with every planner as hydrax's example sets it up: 10 s episodes
from hanging at rest, replanning at 50 Hz over a 1 s horizon, plans held
at 11 knots (zero-order hold); predictive sampling 32 samples at noise 0.1, MPPI 32 at 0.2
with temperature 0.1. CEM (not in hydrax's pendulum example) takes its cart-pole settings
with 32 samples. D2C-MPC replans with one iLQR iteration on models identified every 5th
step of the horizon (docs/mpc.md, "hydrax's tasks"). Every planner's first plan is the
offline D2C optimum's first second: from zero controls at the hanging equilibrium the
cost's gradient vanishes and D2C-MPC never moves. Five episodes per planner, each its own
key."""

import dataclasses

from configs import preset

_SAMPLING = {"sigma_units": "range", "knots": 11, "spline": "zero", "samples": 32}

CONFIG = preset(
    system={"name": "hydrax_pendulum"},
    task={"preset": "hydrax_pendulum_swingup"},
    experiment={"kind": "mpc"},
    mpc={
        "controllers": ("d2c", "predictive_sampling", "mppi", "cem"),
        "horizon": 50,
        "steps": 500,
        "replan_hz": 50.0,
        "horizon_end": "receding",
        "max_iter": 1,
        "sysid.every": 5,
        "n_alphas": 4,
        "process_noise": (0.0,),
        "plants": ("model",),
        "n_episodes": 5,
        "first_plan": "optimum",  # from zeros D2C-MPC sits at the hanging equilibrium (docs/mpc.md)
    },
)
CONFIG = dataclasses.replace(
    CONFIG,
    extensions={
        "mpc.predictive_sampling": {**_SAMPLING, "sigma": 0.1},
        "mpc.mppi": {**_SAMPLING, "sigma": 0.2, "temperature": 0.1},
        "mpc.cem": {**_SAMPLING, "sigma": 0.5, "sigma_min": 0.1, "elites": 3},
    },
)
