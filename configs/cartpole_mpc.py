"""Closed loop on the cartpole: hanging to upright at the origin (the paper's task,
``cartpole_upright``, with its running cost) over 4 s, every controller replanning over
1.5 s, on the model and on a plant 1.1x heavier, under process noise; the rest as
``pendulum_mpc``. The task is finite, so every plan ends at the task's end where that
comes first (``mpc.horizon_end task``): its terminal cost stays at 4 s instead of moving
with each plan. The first plans start from zero controls: the offline optimum juggles the
pole at horizontal for 2.5 s, and closed loops that start from it follow it into
divergence (docs/mpc.md). D2C-MPC's replans identify by forward differences with at most 3
iterations and 4 step sizes. The sampling planners run at their own best settings found
on this task (docs/mpc.md, "Cartpole"), each with a second row at D2C-MPC's budget
(``budget_row``): predictive sampling 512 samples of spread 0.3 (3 N) and 2 iterations
per replan, MPPI 512 samples of 0.3, CEM 512 samples from 1.0 (10 N)."""

import dataclasses

from configs.pendulum_mpc import CONFIG as _PENDULUM
from mjx_surrogate.runs.config import DataConfig, MPCConfig, MPCSysIdConfig, SystemConfig, TaskConfig

CONFIG = dataclasses.replace(
    _PENDULUM,
    system=SystemConfig(name="cartpole", backend="native"),
    task=TaskConfig(preset="cartpole_upright", T=40),
    solver=dataclasses.replace(_PENDULUM.solver, max_iter=300),
    data=DataConfig(n_traj=200),
    mpc=MPCConfig(
        horizon=15,
        steps=40,
        max_iter=3,
        n_alphas=4,
        sysid=MPCSysIdConfig(scheme="forward_difference"),
        horizon_end="task",  # a finite task: its goal stays at 4 s
        process_noise=(0.0, 0.01),
        plants=("model", "mass=1.1"),
        refit_weight=10.0,
        n_episodes=2,
        first_plan="zeros",
    ),
    extensions={
        "mpc.predictive_sampling": {"samples": 512, "sigma": 0.3, "iterations": 2, "budget_row": True},
        "mpc.mppi": {"samples": 512, "sigma": 0.3, "budget_row": True},
        "mpc.cem": {"samples": 512, "budget_row": True},
    },
)
