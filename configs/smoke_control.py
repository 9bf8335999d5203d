"""CI smoke: control with surrogates on the pendulum, tiny sizes."""

from configs import derive

CONFIG = derive(
    "smoke_predict",
    solver={"init": "random"},
    experiment={"kind": "control"},
    data={"levels": (0.1,)},
    surrogate={"sindy.libraries": ("cubic_trig",), "mlp.epochs": 3, "mlp.batch_size": 32},
)
