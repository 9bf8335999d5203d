"""Data-driven iLQR (D2C) on a black-box system, and the exact-Jacobian oracle.

``solve_d2c``: every iteration identifies an LTV model of the black box around the
current nominal (a scheme of :mod:`mjx_surrogate.identification.sysid`), runs the backward pass on it
and the line-searched forward pass on the black box, all inside one jitted ``while_loop``.
``solve_exact``: the same iLQR with exact Jacobians: ``jax.jacfwd`` through the MJX step
(``jacobians="jacfwd"``), or central differences of the black-box step along every
coordinate (``"finite_difference"``: a cheaper reference, no autodiff to compile).
Every solve takes a :class:`~mjx_surrogate.progress.ProgressMeter` (traced: switching it
never recompiles). The same solves driven from the host in chunks, with no callback and so
kept in the persistent compilation cache: :mod:`mjx_surrogate.control.chunked`.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from mjx_surrogate import sharding
from mjx_surrogate.control.ilqr import (
    ClosedLoopFn,
    ILQRParams,
    ILQRResult,
    Problem,
    ilqr_advance,
    ilqr_init,
    ilqr_result,
)
from mjx_surrogate.control.ilqr import closed_loop as ilqr_closed_loop
from mjx_surrogate.identification import sysid as sid
from mjx_surrogate.identification import sysid_reduced  # noqa: F401  (registers the "reduced" scheme)
from mjx_surrogate.progress import NO_PROGRESS, ProgressMeter
from mjx_surrogate.systems.black_box import BlackBox
from mjx_surrogate.systems.system_jit import system_jit
from mjx_surrogate.tasks import Task, task_cost

ORACLES = ("jacfwd", "finite_difference")
METHODS = ("d2c", *ORACLES)  # problem()'s: D2C and the two oracles, by the oracles' own names


def exact_linearize(system: BlackBox, jacobians: str = "jacfwd") -> sid.LinearizeFn:
    """linearize(X, U, K, key) -> Jacobians through the system's differentiable step
    ("jacfwd": MJX, or a JAX function's own) or by coordinate central differences of the
    black-box step."""
    if jacobians not in ORACLES:
        raise ValueError(f"jacobians {jacobians!r}: valid: {', '.join(ORACLES)}")
    if jacobians == "finite_difference":
        return lambda X, U, K, key: sid.finite_difference_jacobians(system.step, X, U)
    jac = system.exact_jacobians_batch  # raises ConfigError for a black box without derivatives
    return lambda X, U, K, key: jac(X[:-1], U)


def problem(system: BlackBox, task: Task, sysid: sid.SysIdParams, method: str) -> Problem:
    """The iLQR problem of one solve: "d2c" on the black box (LTV models, the backend's own
    line-search rollouts), "jacfwd" on the MJX step with ``jax.jacfwd`` Jacobians, or
    "finite_difference" on the black box with coordinate central differences."""
    fine, rank = None, None
    if method == "d2c":
        rank = sysid.n_samples if sid.get_scheme(sysid.scheme).reduced else None
        step, linearize, closed = system.step, sid.ltv_linearize(system, sysid), system.closed_loop
        if (fine_sysid := sid.fine_params(sysid)) is not None:  # every k-th step, then every step
            fine = sid.ltv_linearize(system, fine_sysid)
    elif method == "finite_difference":
        step, linearize, closed = system.step, exact_linearize(system, method), system.closed_loop
    elif method == "jacfwd":
        step, linearize, closed = system.exact_step, exact_linearize(system), None
    else:
        raise ValueError(f"method {method!r}: valid: {', '.join(METHODS)}")
    if system.mesh is not None:
        closed = sharded_trials(step, closed, system.mesh)
    cost = task_cost(task)
    return Problem(step, linearize, cost, task.x0, task.u_min, task.u_max, closed, fine, rank)


def _solve(
    system: BlackBox,
    task: Task,
    U0: jax.Array,
    key: jax.Array,
    params: ILQRParams,
    sysid: sid.SysIdParams,
    method: str,
    progress: ProgressMeter,
) -> ILQRResult:
    """One solve of :func:`problem` from U0 [T, nu], as one program."""
    prob = problem(system, task, sysid, method)
    state = ilqr_init(prob, U0, params, key)
    return ilqr_result(ilqr_advance(prob, state, params, progress=progress))


def sharded_trials(step, closed_loop, mesh) -> ClosedLoopFn:
    """The line search's trial rollouts with the step sizes spread over ``mesh``."""

    def trials(x0, X_bar, U_bar, k, K, alphas, lo, hi):
        def local(a, x0, X_bar, U_bar, k, K, lo, hi):
            if closed_loop is not None:
                return closed_loop(x0, X_bar, U_bar, k, K, a, lo, hi)
            one = lambda alpha: ilqr_closed_loop(step, x0, X_bar, U_bar, k, K, alpha, lo, hi)  # noqa: E731
            return jax.vmap(one)(a)

        return sharding.map_batch(local, mesh, alphas, rest=(x0, X_bar, U_bar, k, K, lo, hi))

    return trials


@system_jit(static_argnames=("system",))
def solve_d2c(
    system: BlackBox,
    task: Task,
    U0: jax.Array,
    key: jax.Array,
    params: ILQRParams = ILQRParams(),
    sysid: sid.SysIdParams = sid.SysIdParams(),
    progress: ProgressMeter = NO_PROGRESS,
) -> ILQRResult:
    """D2C from U0 [T, nu]: LTV identification + iLQR until a stopping rule holds."""
    return _solve(system, task, U0, key, params, sysid, "d2c", progress)


@system_jit(static_argnames=("system", "jacobians"))
def solve_exact(
    system: BlackBox,
    task: Task,
    U0: jax.Array,
    params: ILQRParams = ILQRParams(),
    progress: ProgressMeter = NO_PROGRESS,
    jacobians: str = "jacfwd",
) -> ILQRResult:
    """iLQR from U0 [T, nu] with exact Jacobians (the oracle): ``jacobians`` is "jacfwd"
    (through the MJX step) or "finite_difference" (of the black-box step)."""
    method = check_oracle(jacobians)
    return _solve(system, task, U0, jax.random.key(0), params, sid.SysIdParams(), method, progress)


def check_oracle(jacobians: str) -> str:
    """``jacobians`` if it names an oracle ("jacfwd" or "finite_difference"), else ValueError."""
    if jacobians not in ORACLES:
        raise ValueError(f"jacobians {jacobians!r}: valid: {', '.join(ORACLES)}")
    return jacobians


class MultiStart(NamedTuple):
    best: ILQRResult  # the solve with the lowest final cost
    costs: jax.Array  # [S] final cost of every start
    best_index: jax.Array
    iterations: jax.Array  # [S] every start's iteration count (its black-box effort)
    stop_reasons: jax.Array  # [S] every start's StopReason
    identified: jax.Array  # [S, max_iter] every start's identifications (ILQRResult.identified)


def best_of(results: ILQRResult) -> MultiStart:
    """The multi-start outcome of S solves' results (leading axis S): the lowest finite cost wins."""
    costs = jnp.where(jnp.isfinite(results.cost), results.cost, jnp.inf)
    i = jnp.argmin(costs)
    best = jax.tree.map(lambda a: a[i], results)
    return MultiStart(best, results.cost, i, results.iterations, results.stop_reason, results.identified)


def in_lockstep(system) -> bool:
    """Whether several starts on ``system`` run in lockstep (vmapped), or, for a black box
    stepped on the host (:attr:`Execution.on_host <mjx_surrogate.systems.execution.Execution.on_host>`),
    one after another: there a vmap adds no parallelism (the host call already spreads each
    batch of simulations over its threads) and turns each iteration's conditionals (identify
    or not) into both branches for every start, every start simulating until the last one
    stops."""
    return not system.execution.on_host


def over_starts(system, fn, *starts):
    """fn over the leading (start) axis of ``starts``: ``vmap`` or ``lax.map``
    (:func:`in_lockstep`)."""
    return sharding.over_leading_axis(fn, *starts, lockstep=in_lockstep(system))


@system_jit(static_argnames=("system", "method"))
def solve_multistart(
    system: BlackBox,
    task: Task,
    U0s: jax.Array,
    key: jax.Array,
    params: ILQRParams = ILQRParams(),
    sysid: sid.SysIdParams = sid.SysIdParams(),
    method: str = "d2c",
    progress: ProgressMeter = NO_PROGRESS,
) -> MultiStart:
    """The solve from each of S initial control sequences U0s [S, T, nu] (:func:`over_starts`);
    keeps the best.
    With ``system.mesh`` the starts are spread over its devices (each start's own
    identification and line search stay on its device)."""
    keys = jax.random.split(key, U0s.shape[0])
    single = system.on_one_device()

    def solves(U0s, keys, task, params, sysid, progress):
        one = lambda U0, k: _solve(single, task, U0, k, params, sysid, method, progress)  # noqa: E731
        return over_starts(single, one, U0s, keys)

    results = sharding.map_batch(solves, system.mesh, U0s, keys, rest=(task, params, sysid, progress))
    return best_of(results)
