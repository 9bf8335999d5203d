"""CI smoke: the prediction experiment on the pendulum, tiny sizes."""

from configs import preset

CONFIG = preset(
    system={"backend": "native"},  # compiles in seconds
    task={"preset": "pendulum_swingup", "T": 10},
    solver={"max_iter": 30, "init": "zeros"},
    sysid={"n_samples": 6},
    experiment={"kind": "predict", "progress": False, "video": False, "x64": True},
    data={"n_traj": 40, "levels": (0.1, 0.6)},
    surrogate={"sindy.libraries": ("cubic_trig", "quartic"), "mlp.epochs": 5, "mlp.batch_size": 64},
)
