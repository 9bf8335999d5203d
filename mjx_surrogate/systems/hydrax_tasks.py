"""The pendulum and cart-pole swing-ups of hydrax, the sampling-MPC peer, written from the
facts of its task files (``shared/reference.md``): the same bodies, limits and time steps,
and its costs in this project's convention.

hydrax costs a plan of H steps of dt as sum_t dt l(x_{t+1}, u_t) + phi(x_H), with the angle
term (cos d - 1)^2 + sin^2 d = 2 (1 - cos d) for the angle d from upright: the chordal state
error (``state_error`` "chordal", e = 2 sin(d / 2), e^2 = 2 (1 - cos d)). Written as this
project's J = sum_{t<H} l(x_t, u_t) + l_f(x_H) with Q = 2 dt W, R = 2 dt W_u and Q_f = 2 (W_f
+ dt W) (the running cost's last state moved into the terminal one), J is hydrax's plus dt
times the start's state cost, a constant of the start: the same argmin, the same softmax
weights and elites. :func:`hydrax_cost` gives hydrax's number.

- ``hydrax_pendulum``: a 1 kg link with its centre of mass 0.5 m below the hinge, inertia
  diag(0.087959, 0.087959, 0.00019896) there, tip site at 1 m; theta = 0 hangs, pi is
  upright; a motor of gear 2, ctrl in [-1, 1]; time step 0.02 s, contacts off. Cost
  2 (1 - cos(theta - pi)) + 0.01 dtheta^2 + 0.001 u^2, terminal the same without u.
- ``hydrax_cartpole``: a 1 kg cart on a slider limited to +-1.8 m, a 0.1 kg, 1 m pole
  (capsule radius 0.045) hanging at theta = 0; damping 1e-4 on both joints; a motor on the
  slider of gear 10, ctrl in [-1, 1]; time step 0.01 s, contacts off. Cost 2 (1 -
  cos(theta + pi)) + x^2 + 0.01 |qvel|^2 + 0.01 u^2, terminal 10 x the angle term + x^2 +
  0.01 |qvel|^2.
"""

from __future__ import annotations

import math

import numpy as np

from mjx_surrogate.systems.spec import SystemDefaults
from mjx_surrogate.tasks import TaskPreset, state


def pendulum_xml() -> str:
    """hydrax's pendulum: theta = 0 hangs; Euler, 0.02 s, contacts off."""
    return """<mujoco model="hydrax_pendulum">
  <option timestep="0.02">
    <flag contact="disable" eulerdamp="disable"/>
  </option>
  <statistic center="0 0 1.5" extent="1.6"/>
  <worldbody>
    <light pos="0 -3 3" dir="0 1 -1"/>
    <geom name="pivot" type="box" pos="0 0 1.5" size="0.05 0.05 0.05"/>
    <body name="link" pos="0 0 1.5">
      <joint name="hinge" type="hinge" axis="0 1 0"/>
      <inertial pos="0 0 -0.5" mass="1" diaginertia="0.087959 0.087959 0.00019896"/>
      <geom name="rod" type="capsule" fromto="0 0 0 0 0 -1" size="0.03" mass="0"/>
      <site name="tip" pos="0 0 -1"/>
    </body>
  </worldbody>
  <actuator>
    <motor name="torque" joint="hinge" gear="2" ctrllimited="true" ctrlrange="-1 1"/>
  </actuator>
</mujoco>
"""


def cartpole_xml() -> str:
    """hydrax's cart-pole: theta = 0 hangs; the slider limited to +-1.8 m; 0.01 s."""
    return """<mujoco model="hydrax_cartpole">
  <option timestep="0.01">
    <flag contact="disable"/>
  </option>
  <statistic center="0 0 1.4" extent="2.5"/>
  <worldbody>
    <light pos="0 -3 4" dir="0 1 -1"/>
    <body name="cart" pos="0 0 1">
      <joint name="slider" type="slide" axis="1 0 0" limited="true" range="-1.8 1.8"
             solreflimit="0.08 1" damping="1e-4"/>
      <geom name="cart" type="box" size="0.2 0.15 0.1" mass="1"/>
      <body name="pole">
        <joint name="hinge" type="hinge" axis="0 1 0" damping="1e-4"/>
        <geom name="pole" type="capsule" fromto="0 0 0 0 0 -1" size="0.045" mass="0.1"/>
        <site name="tip" pos="0 0 -1"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor name="force" joint="slider" gear="10" ctrllimited="true" ctrlrange="-1 1"/>
  </actuator>
</mujoco>
"""


def pendulum_config() -> SystemDefaults:
    # the control step is the model's (hydrax plans at the model's time step); MJX: a
    # small model in closed loop (docs/mpc.md)
    return SystemDefaults(pendulum_xml, substeps=1, backend="mjx")


def cartpole_config() -> SystemDefaults:
    return SystemDefaults(cartpole_xml, substeps=1, backend="mjx")


PENDULUM_DT, CARTPOLE_DT = 0.02, 0.01
HORIZON_S = 1.0  # hydrax's plan horizon in its examples


def _weights(dt: float, running: np.ndarray, terminal: np.ndarray, effort: float) -> dict:
    """Q, Q_f, R of this project's convention for hydrax's sum dt l(x_{t+1}, u_t) + phi(x_H)
    with state weights ``running``, ``terminal`` (diagonals) and control weight ``effort``."""
    return dict(
        Q=2 * dt * np.diag(running),
        Q_f=2 * np.diag(terminal + dt * running),
        R=2 * dt * effort * np.eye(1),
        state_error="chordal",
    )


def _pendulum_swingup(nq, nv, nu):
    w = np.array([1.0, 0.01])  # the angle term, 0.01 dtheta^2
    T = round(HORIZON_S / PENDULUM_DT)
    return dict(T=T, x0=state(nq, nv), x_goal=state(nq, nv, q0=math.pi), **_weights(PENDULUM_DT, w, w, 0.001))


def _cartpole_swingup(nq, nv, nu):
    running = np.array([1.0, 1.0, 0.01, 0.01])  # x^2, the angle term, 0.01 |qvel|^2
    terminal = np.array([1.0, 10.0, 0.01, 0.01])
    T = round(HORIZON_S / CARTPOLE_DT)
    fields = _weights(CARTPOLE_DT, running, terminal, 0.01)
    return dict(T=T, x0=state(nq, nv), x_goal=state(nq, nv, q1=math.pi), **fields)


def hydrax_cost(task, J):
    """hydrax's cost of a plan from ``task.x0`` whose cost here is J (module docstring): J
    less the running state cost at x_0 (dt times hydrax's)."""
    from mjx_surrogate.tasks import running_cost

    return J - running_cost(task, task.x0, task.u_ref)


PENDULUM_TASKS = {
    "hydrax_pendulum_swingup": TaskPreset(
        "hydrax_pendulum", _pendulum_swingup, "hydrax: hanging at rest -> upright, 1 s plans, its cost"
    ),
}
CARTPOLE_TASKS = {
    "hydrax_cartpole_swingup": TaskPreset(
        "hydrax_cartpole",
        _cartpole_swingup,
        "hydrax: hanging at rest -> upright at the centre, 1 s plans, its cost",
    ),
}
