"""Pendulum (dm_control's pendulum facts; D2C 2.0 control step 0.1 s = 5 x 0.02 s).

x = [theta, dtheta], theta = 0 upright; one torque motor, not clamped (D2C 2.0).
"""

from __future__ import annotations

import math

import numpy as np

from mjx_surrogate.systems.spec import SystemDefaults
from mjx_surrogate.tasks import TaskPreset, state


def xml() -> str:
    """Torque-driven pendulum, theta = 0 upright; 1 kg tip at 0.5 m, damping 0.1."""
    return """<mujoco model="pendulum">
  <option timestep="0.02" integrator="Euler" gravity="0 0 -9.81"/>
  <worldbody>
    <body name="pole" pos="0 0 1">
      <joint name="hinge" type="hinge" axis="0 1 0" damping="0.1"/>
      <geom name="rod" type="capsule" fromto="0 0 0 0 0 0.5" size="0.02" mass="0"
            contype="0" conaffinity="0"/>
      <geom name="tip" type="sphere" pos="0 0 0.5" size="0.05" mass="1"
            contype="0" conaffinity="0"/>
    </body>
  </worldbody>
  <actuator>
    <motor name="torque" joint="hinge" gear="1" ctrllimited="false"/>
  </actuator>
</mujoco>
"""


def default_config() -> SystemDefaults:
    # dt 0.1 s per control step, as in D2C 2.0; MJX wins on 2 cores (docs/performance.md).
    return SystemDefaults(xml, substeps=5, backend="mjx")


def _pendulum_d2c(nq, nv, nu):
    return dict(
        T=30,
        x0=state(nq, nv, q0=math.pi - 0.1),
        x_goal=state(nq, nv),
        Q=np.zeros((2, 2)),
        Q_f=900 * np.diag([1.0, 0.1]),
        R=0.01 * np.eye(1),
    )


def _pendulum_swingup(nq, nv, nu):
    return dict(
        T=30,
        x0=state(nq, nv, q0=math.pi),
        x_goal=state(nq, nv, q0=math.pi / 3),
        Q=np.zeros((2, 2)),
        Q_f=900 * np.diag([1.0, 0.1]),
        R=0.01 * np.eye(1),
    )


TASKS = {
    "pendulum_d2c": TaskPreset("pendulum", _pendulum_d2c, "D2C 2.0: theta = pi - 0.1 -> 0 (upright), T 30"),
    "pendulum_swingup": TaskPreset("pendulum", _pendulum_swingup, "paper: 180 deg -> rest at 60 deg, T 30"),
}
