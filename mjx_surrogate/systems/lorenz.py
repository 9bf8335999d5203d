"""The Lorenz system with control, a black box that is not a MuJoCo model.

Equations and parameters of SINDy-MPC (Kaiser, Kutz and Brunton, "Sparse identification
of nonlinear dynamics for model predictive control in the low-data limit", Proc. R. Soc.
A 474: 20180335, 2018, Section 4; Lorenz 1963), the control acting on the first state:

    dx1/dt = sigma (x2 - x1) + u,   dx2/dt = x1 (rho - x3) - x2,   dx3/dt = x1 x2 - beta x3

sigma = 10, rho = 28, beta = 8/3. One control step: u held for ``dt`` (default 0.01 s,
ten classical Runge-Kutta steps of 1 ms, SINDy-MPC's time step). Tasks: ``lorenz_switch``
moves from the fixed point C- = (-sqrt(beta (rho - 1)), same, rho - 1) to C+ in 2 s (200
steps); ``lorenz_stabilize`` is SINDy-MPC's published control task (its authors' code,
github.com/eurika-kaiser/SINDY-MPC, EX_LORENZ: 5 time units of MPC at 0.01 with a
horizon of 10 steps, state weights Q = I, control weight 1e-3, |u| <= 50, towards C-)
from the start of its training data, (-8, 8, 27), a point of the attractor's basin.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np

from mjx_surrogate.systems.function import FunctionSystem, from_jax, rk4
from mjx_surrogate.tasks import Task, TaskPreset, make_task

SIGMA, RHO, BETA = 10.0, 28.0, 8.0 / 3.0
C_PLUS = np.array([math.sqrt(BETA * (RHO - 1)), math.sqrt(BETA * (RHO - 1)), RHO - 1])
C_MINUS = C_PLUS * np.array([-1.0, -1.0, 1.0])


def vector_field(x, u, sigma: float = SIGMA, rho: float = RHO, beta: float = BETA):
    """dx/dt [3] at x [3], u [1]."""
    return jnp.stack([sigma * (x[1] - x[0]) + u[0], x[0] * (rho - x[2]) - x[1], x[0] * x[1] - beta * x[2]])


def make_system(
    dt: float = 0.01, substeps: int = 10, sigma: float = SIGMA, rho: float = RHO, beta: float = BETA
) -> FunctionSystem:
    """The controlled Lorenz system; sigma, rho, beta: other parameters (an MPC plant, e.g.
    ``rho=30``)."""
    return from_jax(
        rk4(lambda x, u: vector_field(x, u, sigma, rho, beta), dt, substeps),
        3,
        1,
        dt,
        name="lorenz",
        state_labels=("x1", "x2", "x3"),
        control_labels=("u",),
    )


def switch_fields(T: int = 200, u_max: float = 50.0) -> dict:
    """C- -> C+ in T steps: Q_f 100 I at the end, 0.01 I on the way, R 1e-4, |u| <= u_max
    (SINDy-MPC's bound is 50)."""
    return dict(
        x0=C_MINUS,
        x_goal=C_PLUS,
        Q=0.01 * np.eye(3),
        Q_f=100.0 * np.eye(3),
        R=1e-4 * np.eye(1),
        T=T,
        u_min=np.array([-u_max]),
        u_max=np.array([u_max]),
        u_ref=np.zeros(1),
    )


def switch_task(T: int = 200, u_max: float = 50.0) -> Task:
    """The task of :func:`switch_fields`."""
    return make_task(**switch_fields(T, u_max))


def stabilize_fields(T: int = 500) -> dict:
    """SINDy-MPC's task: (-8, 8, 27) -> C-, running cost (x - C-)' I (x - C-) + 1e-3 u^2
    (its rate penalty on u, 1e-3 (u_t - u_{t-1})^2, has no term here), |u| <= 50."""
    return dict(
        x0=np.array([-8.0, 8.0, 27.0]),
        x_goal=C_MINUS,
        Q=np.eye(3),
        Q_f=np.eye(3),
        R=1e-3 * np.eye(1),
        T=T,
        u_min=np.array([-50.0]),
        u_max=np.array([50.0]),
        u_ref=np.zeros(1),
    )


TASKS = {
    "lorenz_switch": TaskPreset(
        "lorenz",
        lambda nq, nv, nu: switch_fields(),
        "SINDy-MPC's Lorenz: C- -> C+ in 2 s (200 steps), |u| <= 50",
    ),
    "lorenz_stabilize": TaskPreset(
        "lorenz",
        lambda nq, nv, nu: stabilize_fields(),
        "SINDy-MPC's published task: (-8, 8, 27) -> C- in 5 s (500 steps), Q = I, R = 1e-3",
    ),
}
