"""Closed loop on the cartpole: hanging to upright at the origin (the paper's task,
``cartpole_upright``, with its running cost) over 4 s, every controller replanning over
1.5 s, on the model and on a plant 1.1x heavier, under process noise; the rest as
``pendulum_mpc``. The first plans start from zero controls: the offline optimum juggles the
pole at horizontal for 2.5 s, and closed loops that start from it follow it into
divergence (docs/mpc.md). D2C-MPC's replans identify by forward differences with at most 3
iterations and 4 step sizes: over 2 s with the solver's central differences, 5 iterations
and 8 step sizes its closed loops cost 2412-2529 at 1.1-1.7x real time on 2 cores, over
1.5 s with these 2059-2729 at 2.9-4.1x (docs/mpc.md)."""

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
        horizon_end="receding",  # every plan H ahead, as measured in docs/mpc.md
        process_noise=(0.0, 0.01),
        plants=("model", "mass=1.1"),
        refit_weight=10.0,
        n_episodes=2,
        first_plan="zeros",
    ),
)
