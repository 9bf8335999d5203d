"""Data-driven iLQR (D2C) on a black-box system, and the exact-Jacobian oracle.

``solve_d2c``: every iteration identifies an LTV model of the black box around the
current nominal (:mod:`mjx_surrogate.sysid`), runs the backward pass on it and the
line-searched forward pass on the black box, all inside one jitted ``while_loop``.
``solve_exact``: the same iLQR with A_t, B_t = ``jax.jacfwd`` through the MJX step.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp

from mjx_surrogate import sysid as sid
from mjx_surrogate.ilqr import Cost, ILQRParams, ILQRResult, ilqr
from mjx_surrogate.systems import System
from mjx_surrogate.tasks import Task, running_cost, terminal_cost


def task_cost(task: Task) -> Cost:
    """The task's quadratic cost as the solver's :class:`~mjx_surrogate.ilqr.Cost`."""
    return Cost(functools.partial(running_cost, task), functools.partial(terminal_cost, task))


def ltv_linearize(system: System, p: sid.SysIdParams):
    """linearize(X, U, K, key) -> (A, B) from black-box samples with scheme ``p.scheme``."""
    if p.scheme in ("central_difference", "forward_difference"):
        one_step = getattr(sid, p.scheme)
        return lambda X, U, K, key: one_step(system.step, X, U, key, p)
    if p.scheme == "rollout":
        return lambda X, U, K, key: sid.open_loop_rollouts(system.rollout, X, U, key, p)
    if p.scheme == "closed_loop":
        return lambda X, U, K, key: sid.closed_loop_rollouts(system.step, X, U, K, key, p)
    raise ValueError(f"solver.sysid: unknown scheme {p.scheme!r}; valid: {sid.SCHEMES}")


def exact_linearize(system: System):
    """linearize(X, U, K, key) -> exact Jacobians through the differentiable MJX step."""
    return lambda X, U, K, key: sid.exact_jacobians(system.mjx_step, X, U)


def _solve(system: System, task: Task, U0: jax.Array, key: jax.Array, params: ILQRParams,
           sysid: sid.SysIdParams, method: str) -> ILQRResult:
    """One iLQR solve: "d2c" on the black box (LTV models, the backend's own line-search
    rollouts) or "exact" on the MJX step with ``jax.jacfwd`` Jacobians."""
    if method == "d2c":
        return ilqr(system.step, ltv_linearize(system, sysid), task_cost(task), task.x0, U0,
                    task.u_min, task.u_max, params, key, system.closed_loop)
    return ilqr(system.mjx_step, exact_linearize(system), task_cost(task), task.x0, U0,
                task.u_min, task.u_max, params, key)


@functools.partial(jax.jit, static_argnames=("system",))
def solve_d2c(system: System, task: Task, U0: jax.Array, key: jax.Array,
              params: ILQRParams = ILQRParams(),
              sysid: sid.SysIdParams = sid.SysIdParams()) -> ILQRResult:
    """D2C from U0 [T, nu]: LTV identification + iLQR until a stopping rule holds."""
    return _solve(system, task, U0, key, params, sysid, "d2c")


@functools.partial(jax.jit, static_argnames=("system",))
def solve_exact(system: System, task: Task, U0: jax.Array,
                params: ILQRParams = ILQRParams()) -> ILQRResult:
    """Model-based iLQR from U0 [T, nu] with exact MJX Jacobians (the oracle)."""
    return _solve(system, task, U0, jax.random.key(0), params, sid.SysIdParams(), "exact")


class MultiStart(NamedTuple):
    best: ILQRResult  # the solve with the lowest final cost
    costs: jax.Array  # [S] final cost of every start
    best_index: jax.Array


@functools.partial(jax.jit, static_argnames=("system", "method"))
def solve_multistart(system: System, task: Task, U0s: jax.Array, key: jax.Array,
                     params: ILQRParams = ILQRParams(),
                     sysid: sid.SysIdParams = sid.SysIdParams(),
                     method: str = "d2c") -> MultiStart:
    """vmap of the solve over S initial control sequences U0s [S, T, nu]; keeps the best."""
    keys = jax.random.split(key, U0s.shape[0])
    results = jax.vmap(lambda U0, k: _solve(system, task, U0, k, params, sysid, method))(
        U0s, keys)
    costs = jnp.where(jnp.isfinite(results.cost), results.cost, jnp.inf)
    i = jnp.argmin(costs)
    return MultiStart(jax.tree.map(lambda a: a[i], results), results.cost, i)


def initial_controls(key: jax.Array, T: int, nu: int, kind: str, scale: float,
                     n: int | None = None, dtype=None) -> jax.Array:
    """U0 [T, nu] (or [n, T, nu]): zeros, or N(0, scale^2) random controls."""
    shape = (T, nu) if n is None else (n, T, nu)
    dtype = dtype or jnp.asarray(0.0).dtype
    if kind == "zeros":
        return jnp.zeros(shape, dtype)
    return scale * jax.random.normal(key, shape, dtype)


def simulated_steps(result: ILQRResult, T: int, n_alphas: int, sysid: sid.SysIdParams) -> int:
    """Control steps simulated by a D2C solve: identifications + forward passes + initial."""
    import numpy as np

    h = np.asarray(result.cost_history)
    it = int(result.iterations)
    accepted = int(np.sum(h[1 : it + 1] < h[:it]))
    per_id = {"central_difference": 2 * sysid.n_samples * T,
              "forward_difference": (sysid.n_samples + 1) * T,
              "rollout": sysid.n_samples * T, "closed_loop": sysid.n_samples * T}[sysid.scheme]
    return T + it * n_alphas * T + min(accepted + 1, it) * per_id
