"""The F-8 Crusader's longitudinal dynamics, a black box that is not a MuJoCo model.

The cubic model of Garrard and Jordan ("Design of nonlinear automatic flight control
systems", Automatica 13(5), 1977), at 30 000 ft and Mach 0.85, as used by SINDy-MPC
(Kaiser, Kutz and Brunton, Proc. R. Soc. A 474: 20180335, 2018, Section 5): x1 the angle
of attack, x2 the pitch angle, x3 the pitch rate (rad, rad/s), u the tail deflection
(rad):

    dx1/dt = -0.877 x1 + x3 - 0.088 x1 x3 + 0.47 x1^2 - 0.019 x2^2 - x1^2 x3 + 3.846 x1^3
             - 0.215 u + 0.28 x1^2 u + 0.47 x1 u^2 + 0.63 u^3
    dx2/dt = x3
    dx3/dt = -4.208 x1 - 0.396 x3 - 0.47 x1^2 - 3.564 x1^3
             - 20.967 u + 6.265 x1^2 u + 46 x1 u^2 + 61.4 u^3

One control step: u held for ``dt`` (default 0.02 s, four classical Runge-Kutta steps).
The task (Garrard and Jordan's recovery): from an angle of attack of 26.7 deg (0.4655
rad) back to level flight, x = 0, in 5 s (250 steps), the tail deflection within +-0.3 rad.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from mjx_surrogate.systems.function import FunctionSystem, from_jax, rk4
from mjx_surrogate.tasks import Task, TaskPreset, make_task


def vector_field(x, u):
    """dx/dt [3] at x [3], u [1]."""
    a, q, v = x[0], x[1], x[2]
    w = u[0]
    da = (
        -0.877 * a
        + v
        - 0.088 * a * v
        + 0.47 * a**2
        - 0.019 * q**2
        - a**2 * v
        + 3.846 * a**3
        - 0.215 * w
        + 0.28 * a**2 * w
        + 0.47 * a * w**2
        + 0.63 * w**3
    )
    dv = (
        -4.208 * a
        - 0.396 * v
        - 0.47 * a**2
        - 3.564 * a**3
        - 20.967 * w
        + 6.265 * a**2 * w
        + 46.0 * a * w**2
        + 61.4 * w**3
    )
    return jnp.stack([da, v, dv])


def make_system(dt: float = 0.02, substeps: int = 4) -> FunctionSystem:
    return from_jax(
        rk4(vector_field, dt, substeps),
        3,
        1,
        dt,
        name="f8",
        u_min=-0.3,
        u_max=0.3,
        state_labels=("alpha", "theta", "q"),
        control_labels=("tail",),
    )


def recovery_fields(T: int = 250) -> dict:
    """alpha 0.4655 rad -> level flight (x = 0) in T steps: Q I, Q_f 1000 I, R 0.01,
    |u| <= 0.3 rad."""
    return dict(
        x0=np.array([0.4655, 0.0, 0.0]),
        x_goal=np.zeros(3),
        Q=np.eye(3),
        Q_f=1000.0 * np.eye(3),
        R=0.01 * np.eye(1),
        T=T,
        u_min=np.array([-0.3]),
        u_max=np.array([0.3]),
        u_ref=np.zeros(1),
    )


def recovery_task(T: int = 250) -> Task:
    """The task of :func:`recovery_fields`."""
    return make_task(**recovery_fields(T))


TASKS = {
    "f8_recovery": TaskPreset(
        "f8",
        lambda nq, nv, nu: recovery_fields(),
        "F-8 (Garrard and Jordan): alpha 26.7 deg -> level flight in 5 s",
    ),
}
