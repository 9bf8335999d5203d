"""CI smoke: MPC on the pendulum, every controller, tiny sizes, noise and a plant that is
heavier, longer and more damped than the model; predictive sampling at its own 8 samples
beside D2C-MPC's budget (``budget_row``), the others at that budget."""

import dataclasses

from configs import derive

CONFIG = derive(
    "pendulum_mpc",
    task={"T": 8},
    solver={"max_iter": 30},
    experiment={"progress": False, "oracle": "finite_difference"},
    data={"n_traj": 40},
    surrogate={"mlp.epochs": 3, "mlp.batch_size": 32},
    mpc={
        "horizon": 5,
        "steps": 6,
        "horizon_end": "auto",  # the default: every plan ends at the task's end (step 8) or 5 ahead
        "max_iter": 2,
        "process_noise": (0.0, 0.01),
        "plants": ("mass=1.2,length=1.1,damping=2",),
        "n_episodes": 2,
    },
)
CONFIG = dataclasses.replace(
    CONFIG, extensions={"mpc.predictive_sampling": {"samples": 8, "budget_row": True}}
)
