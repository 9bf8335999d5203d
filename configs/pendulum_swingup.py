"""Paper: pendulum swing-up from 180 deg to rest at 60 deg in 30 steps, from zero controls
(the cartpole's swing-up with 10 samples and 100 iterations)."""

from configs import derive

CONFIG = derive(
    "cartpole_swingup",
    system={"name": "pendulum"},
    task={"preset": "pendulum_swingup"},
    solver={"max_iter": 100},
    sysid={"n_samples": 10},
)
