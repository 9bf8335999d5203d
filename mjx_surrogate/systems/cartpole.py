"""Cart-pole (dm_control's cartpole facts; D2C 2.0 control step 0.1 s = 10 RK4 x 0.01 s).

x = [cart x, pole angle, dx, dangle], angle 0 upright; one force on the cart, not clamped.
"""

from __future__ import annotations

import math

import numpy as np

from mjx_surrogate.systems.spec import SystemDefaults
from mjx_surrogate.tasks import TaskPreset, state


def xml() -> str:
    """Cart on an unlimited rail with a 1 m, 0.1 kg pole; theta = 0 upright; RK4, dt 0.01."""
    return """<mujoco model="cartpole">
  <option timestep="0.01" integrator="RK4" gravity="0 0 -9.81"/>
  <worldbody>
    <body name="cart" pos="0 0 1">
      <joint name="slider" type="slide" axis="1 0 0" damping="0"/>
      <geom name="cart" type="box" size="0.2 0.15 0.1" mass="1"
            contype="0" conaffinity="0"/>
      <body name="pole" pos="0 0 0">
        <joint name="hinge" type="hinge" axis="0 1 0" damping="0"/>
        <geom name="pole" type="capsule" fromto="0 0 0 0 0 1" size="0.045" mass="0.1"
              contype="0" conaffinity="0"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor name="force" joint="slider" gear="10" ctrllimited="false"/>
  </actuator>
</mujoco>
"""


def default_config() -> SystemDefaults:
    # dt 0.1 s per control step (D2C 2.0), 10 RK4 steps of 0.01 s.
    return SystemDefaults(xml, substeps=10, backend="mjx")


_CP_Q = 5 * np.diag([2.0, 8.0, 0.2, 0.3])
_CP_QF = 900 * np.diag([3.0, 10.0, 3.0, 3.0])


def _cartpole_d2c(nq, nv, nu):
    return dict(
        T=30,
        x0=state(nq, nv, q1=math.pi - 0.3),
        x_goal=state(nq, nv),
        Q=_CP_Q,
        Q_f=_CP_QF,
        R=0.005 * np.eye(1),
    )


def _cartpole_swingup(nq, nv, nu):
    # The paper's set-up "similar to the pendulum": terminal cost only and the force limited
    # to +-1 (10 N). D2C 2.0's running cost towards a pole at 60 deg, which a cart at rest
    # cannot hold, makes the optimum juggle the pole with 120-175 N kicks (open-loop gain
    # 3.9e5, docs/method.md "Locality"); then no model, the LTV included, stays local.
    return dict(
        T=30,
        x0=state(nq, nv, q1=math.pi),
        x_goal=state(nq, nv, q1=math.pi / 3),
        Q=np.zeros((4, 4)),
        Q_f=_CP_QF,
        R=0.005 * np.eye(1),
        u_min=-np.ones(1),
        u_max=np.ones(1),
    )


def _cartpole_upright(nq, nv, nu):
    return dict(
        T=30, x0=state(nq, nv, q1=math.pi), x_goal=state(nq, nv), Q=_CP_Q, Q_f=_CP_QF, R=0.005 * np.eye(1)
    )


TASKS = {
    "cartpole_d2c": TaskPreset(
        "cartpole", _cartpole_d2c, "D2C 2.0: theta = pi - 0.3 -> upright at the origin, T 30"
    ),
    "cartpole_swingup": TaskPreset(
        "cartpole",
        _cartpole_swingup,
        "paper: 180 deg -> rest at 60 deg, T 30, terminal cost, |u| <= 1 (10 N)",
    ),
    "cartpole_upright": TaskPreset(
        "cartpole", _cartpole_upright, "paper: hanging -> upright at the origin, T 30"
    ),
}
