"""Paper: cartpole from hanging to upright at the origin, from a random trajectory (the
swing-up preset's solver otherwise)."""

from configs import derive

CONFIG = derive("cartpole_swingup", task={"preset": "cartpole_upright"}, solver={"init": "random"})
