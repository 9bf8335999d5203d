"""Closed loop on the pendulum: every controller replans from the measured state (D2C-MPC,
the exact oracle's MPC, SINDy- and MLP-MPC, predictive sampling, MPPI and CEM) or tracks
the offline optimum (TVLQR), on the model, on a 1.5x heavier plant and on a 1.2x longer
one with twice the damping, under process noise; SINDy-MPC also refitted online from each
episode's own transitions (each weighing 10 training ones). The task is D2C 2.0's
swing-up with a running state cost (Q = 0.01 Q_f) over 6 s, and every plan ends at the
task's end where that comes first (``mpc.horizon_end task``): with a terminal cost 3 s
ahead of every state the sampling planners reached the goal less often, D2C-MPC the same
(docs/mpc.md). The sampling planners run at their own best settings found on this task,
each with a second row at D2C-MPC's budget (``budget_row``): predictive sampling and MPPI
512 samples of spread 3 (N m), CEM 512 samples from 0.3."""

import dataclasses

from configs import preset

CONFIG = preset(
    system={"backend": "native"},
    task={"T": 60, "Q_diag": (9.0, 0.9)},
    experiment={"kind": "mpc", "x64": True},
    data={"n_traj": 200},
    surrogate={"sindy.libraries": ("cubic_trig",), "mlp.epochs": 200},
    mpc={
        "horizon": 30,
        "steps": 60,
        "max_iter": 5,
        "horizon_end": "task",  # a finite swing-up: its terminal cost stays at 6 s
        "process_noise": (0.0, 0.02, 0.05),
        "plants": ("model", "mass=1.5", "length=1.2,damping=2"),
        "refit_weight": 10.0,
        "n_episodes": 4,
    },
)
CONFIG = dataclasses.replace(
    CONFIG,
    extensions={
        "mpc.predictive_sampling": {"samples": 512, "sigma": 3.0, "budget_row": True},
        "mpc.mppi": {"samples": 512, "sigma": 3.0, "budget_row": True},
        "mpc.cem": {"samples": 512, "sigma": 0.3, "budget_row": True},
    },
)
