"""Closed loop on the pendulum: every controller replans from the measured state (D2C-MPC,
the exact oracle's MPC, SINDy- and MLP-MPC, predictive sampling and MPPI at D2C-MPC's
black-box budget) or tracks the offline optimum (TVLQR), on the model, on a 1.5x heavier
plant and on a 1.2x longer one with twice the damping, under process noise; SINDy-MPC also
refitted online from each episode's own transitions (each weighing 10 training ones). The
task is D2C 2.0's swing-up with a running state cost (Q = 0.01 Q_f): with the paper's
terminal-only cost a receding horizon keeps postponing the swing, which plans that end at
the task's end (``mpc.horizon_end task``) do not (docs/mpc.md)."""

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
        "horizon_end": "receding",  # a regulation task: every plan H ahead, as measured in docs/mpc.md
        "process_noise": (0.0, 0.02, 0.05),
        "plants": ("model", "mass=1.5", "length=1.2,damping=2"),
        "refit_weight": 10.0,
        "n_episodes": 4,
    },
)
