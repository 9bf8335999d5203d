"""Quadratic tracking tasks; presets live with their systems (``mjx_surrogate.systems``).

Cost convention (one for the whole project, docs/results.md):

    J = sum_{t<T} [ 1/2 (x_t - x*)' Q (x_t - x*) + 1/2 u_t' R u_t ]
        + 1/2 (x_T - x*)' Q_f (x_T - x*)
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from mjx_surrogate import cost as cost_lib


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


def task_cost(task: Task) -> cost_lib.Cost:
    """The task's quadratic cost as the solver's :class:`~mjx_surrogate.cost.Cost`."""
    return cost_lib.Cost(lambda x, u: running_cost(task, x, u), lambda x: terminal_cost(task, x))


def trajectory_cost(task: Task, X: jax.Array, U: jax.Array) -> jax.Array:
    """J of X [T+1, nx], U [T, nu] (+inf if X is not finite or blew up); batch with vmap."""
    return cost_lib.trajectory_cost(task_cost(task), X, U)


class TaskPreset(NamedTuple):
    """A preset: the system it belongs to and a builder (nq, nv, nu) -> dict of numpy fields."""

    system: str
    build: Callable[[int, int, int], dict]
    doc: str


def state(nq: int, nv: int, **qpos: float) -> np.ndarray:
    """A state [nq + nv] of zeros with the named qpos entries set: ``state(2, 2, q0=pi)``."""
    x = np.zeros(nq + nv)
    for idx, v in qpos.items():
        x[int(idx[1:])] = v
    return x


def make_task(x0, x_goal, Q, Q_f, R, T: int, u_min=None, u_max=None, dtype=None) -> Task:
    """Assemble a :class:`Task` from array-likes (shapes checked by ``setup.resolve``)."""
    dtype = dtype or jnp.asarray(0.0).dtype
    nu = np.shape(R)[0]
    lo = np.full(nu, -np.inf) if u_min is None else np.asarray(u_min, float)
    hi = np.full(nu, np.inf) if u_max is None else np.asarray(u_max, float)
    arr = lambda a: jnp.asarray(np.asarray(a, float), dtype)  # noqa: E731
    return Task(arr(x0), arr(x_goal), arr(Q), arr(Q_f), arr(R), arr(lo), arr(hi), int(T))
