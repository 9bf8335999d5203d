"""Quadratic tracking tasks and their presets.

Cost convention (one for the whole project, docs/results.md):

    J = sum_{t<T} [ 1/2 (x_t - x*)' Q (x_t - x*) + 1/2 u_t' R u_t ]
        + 1/2 (x_T - x*)' Q_f (x_T - x*)
"""

from __future__ import annotations

import math
from typing import Callable, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct


@struct.dataclass
class Task:
    """x0, x_goal [nx]; Q, Q_f [nx, nx]; R [nu, nu]; u_min, u_max [nu] (may be +-inf)."""

    x0: jax.Array
    x_goal: jax.Array
    Q: jax.Array
    Q_f: jax.Array
    R: jax.Array
    u_min: jax.Array
    u_max: jax.Array
    T: int = struct.field(pytree_node=False)


def running_cost(task: Task, x: jax.Array, u: jax.Array) -> jax.Array:
    """1/2 dx' Q dx + 1/2 u' R u for x [nx], u [nu]."""
    dx = x - task.x_goal
    return 0.5 * dx @ task.Q @ dx + 0.5 * u @ task.R @ u


def terminal_cost(task: Task, x: jax.Array) -> jax.Array:
    dx = x - task.x_goal
    return 0.5 * dx @ task.Q_f @ dx


def trajectory_cost(task: Task, X: jax.Array, U: jax.Array) -> jax.Array:
    """J of X [T+1, nx], U [T, nu]; batch with ``jax.vmap``."""
    run = jax.vmap(lambda x, u: running_cost(task, x, u))(X[:-1], U)
    return run.sum() + terminal_cost(task, X[-1])


class TaskPreset(NamedTuple):
    """A preset: the system it belongs to and a builder (nq, nv, nu) -> dict of numpy fields."""

    system: str
    build: Callable[[int, int, int], dict]
    doc: str


def _state(nq: int, nv: int, **qpos: float) -> np.ndarray:
    x = np.zeros(nq + nv)
    for idx, v in qpos.items():
        x[int(idx[1:])] = v
    return x


def _pendulum_d2c(nq, nv, nu):
    return dict(T=30, x0=_state(nq, nv, q0=math.pi - 0.1), x_goal=_state(nq, nv),
                Q=np.zeros((2, 2)), Q_f=900 * np.diag([1.0, 0.1]), R=0.01 * np.eye(1))


def _pendulum_swingup(nq, nv, nu):
    return dict(T=30, x0=_state(nq, nv, q0=math.pi), x_goal=_state(nq, nv, q0=math.pi / 3),
                Q=np.zeros((2, 2)), Q_f=900 * np.diag([1.0, 0.1]), R=0.01 * np.eye(1))


_CP_Q = 5 * np.diag([2.0, 8.0, 0.2, 0.3])
_CP_QF = 900 * np.diag([3.0, 10.0, 3.0, 3.0])


def _cartpole_d2c(nq, nv, nu):
    return dict(T=30, x0=_state(nq, nv, q1=math.pi - 0.3), x_goal=_state(nq, nv),
                Q=_CP_Q, Q_f=_CP_QF, R=0.005 * np.eye(1))


def _cartpole_swingup(nq, nv, nu):
    return dict(T=30, x0=_state(nq, nv, q1=math.pi), x_goal=_state(nq, nv, q1=math.pi / 3),
                Q=_CP_Q, Q_f=_CP_QF, R=0.005 * np.eye(1))


def _cartpole_upright(nq, nv, nu):
    return dict(T=30, x0=_state(nq, nv, q1=math.pi), x_goal=_state(nq, nv),
                Q=_CP_Q, Q_f=_CP_QF, R=0.005 * np.eye(1))


def _fish_d2c(nq, nv, nu):
    x0 = _state(nq, nv, q3=1.0)
    goal = _state(nq, nv, q1=0.4, q2=0.2, q3=1.0)
    w = np.zeros(nq + nv)
    w[:3] = 1.0
    return dict(T=600, x0=x0, x_goal=goal, Q=9 * np.diag(w), Q_f=1500 * np.diag(w),
                R=0.1 * np.eye(nu))


def _swimmer_nose(T):
    def build(nq, nv, nu):
        w = np.zeros(nq + nv)
        w[:2] = 1.0  # the root body's origin is the nose: qpos[0:2]
        return dict(T=T, x0=_state(nq, nv), x_goal=_state(nq, nv, q0=0.5, q1=-0.6),
                    Q=10 * np.diag(w), Q_f=1000 * np.diag(w), R=0.01 * np.eye(nu))
    return build


TASK_PRESETS: dict[str, TaskPreset] = {
    "pendulum_d2c": TaskPreset("pendulum", _pendulum_d2c,
                               "D2C 2.0: theta = pi - 0.1 -> 0 (upright), T 30"),
    "pendulum_swingup": TaskPreset("pendulum", _pendulum_swingup,
                                   "paper: 180 deg -> rest at 60 deg, T 30"),
    "cartpole_d2c": TaskPreset("cartpole", _cartpole_d2c,
                               "D2C 2.0: theta = pi - 0.3 -> upright at the origin, T 30"),
    "cartpole_swingup": TaskPreset("cartpole", _cartpole_swingup,
                                   "paper: 180 deg -> rest at 60 deg, T 30"),
    "cartpole_upright": TaskPreset("cartpole", _cartpole_upright,
                                   "paper: hanging -> upright at the origin, T 30"),
    "fish_d2c": TaskPreset("fish", _fish_d2c,
                           "D2C 2.0: rest -> (0, 0.4, 0.2), quaternion w = 1, T 600"),
    "swimmer3_d2c": TaskPreset("swimmer3", _swimmer_nose(900), "D2C 2.0: nose -> (0.5, -0.6), T 900"),
    "swimmer6_d2c": TaskPreset("swimmer6", _swimmer_nose(800), "D2C 2.0: nose -> (0.5, -0.6), T 800"),
    "swimmer_nose": TaskPreset("swimmer*", _swimmer_nose(300),
                               "any swimmerN: nose -> (0.5, -0.6), T 300"),
}


def make_task(x0, x_goal, Q, Q_f, R, T: int, u_min=None, u_max=None, dtype=None) -> Task:
    """Assemble a :class:`Task` from array-likes (shapes checked by ``setup.resolve``)."""
    dtype = dtype or jnp.asarray(0.0).dtype
    nu = np.shape(R)[0]
    lo = np.full(nu, -np.inf) if u_min is None else np.asarray(u_min, float)
    hi = np.full(nu, np.inf) if u_max is None else np.asarray(u_max, float)
    arr = lambda a: jnp.asarray(np.asarray(a, float), dtype)  # noqa: E731
    return Task(arr(x0), arr(x_goal), arr(Q), arr(Q_f), arr(R), arr(lo), arr(hi), int(T))
