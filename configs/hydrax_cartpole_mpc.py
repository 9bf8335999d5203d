"""hydrax's cart-pole swing-up (``hydrax_cartpole``: its model, cost and loop, from the
facts of its task files) with every planner as hydrax's example sets it up: 10 s episodes
from hanging at rest, replanning at 50 Hz (every second 0.01 s step) over a 1 s horizon,
plans held at 4 knots of a cubic spline; predictive sampling and MPPI
128 samples at noise 0.3 (MPPI's temperature 0.1), CEM 128 samples, 3 elites, spread 0.5
down to at least 0.1. D2C-MPC as in ``hydrax_pendulum_mpc``. Five episodes per planner."""

import dataclasses

from configs import derive

_SAMPLING = {"sigma_units": "range", "knots": 4, "spline": "cubic", "samples": 128}

CONFIG = derive(
    "hydrax_pendulum_mpc",
    system={"name": "hydrax_cartpole"},
    task={"preset": "hydrax_cartpole_swingup"},
    mpc={"horizon": 100, "steps": 1000},
)
CONFIG = dataclasses.replace(
    CONFIG,
    extensions={
        "mpc.predictive_sampling": {**_SAMPLING, "sigma": 0.3},
        "mpc.mppi": {**_SAMPLING, "sigma": 0.3, "temperature": 0.1},
        "mpc.cem": {**_SAMPLING, "sigma": 0.5, "sigma_min": 0.1, "elites": 3},
    },
)
