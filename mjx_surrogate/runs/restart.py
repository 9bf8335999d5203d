"""Restarts of a solve that stopped where its local models see no way down: distinct
starts around it, the best kept.

A solve that ends ``stationary`` stopped at its start: every local model there says the
controls do not change the cost (dm_control's finger, away from the spinner it should
turn, touches nothing the cost weighs). Local models cannot see past that, but other
starts can: the same solve from ``n`` starts, each the stationary start plus
N(0, half range^2) per control (clipped to the limits; half range 1 where a control is
unlimited), keeps the best.

A solve that ends ``stalled`` found no step its local models promise and the black box
grants: on a contact model the contacts switch along the nominal and the models fitted
across them stop agreeing with the simulator. Its end is often a poorer local minimum
than a nearby start reaches (the dm_control humanoid holding its pose: 3.47 from the hold
start, 1.38 from starts a quarter of the actuators' half range away; docs/performance.md).
:func:`restart_stalled` solves again from ``n`` starts spread that far around the stalled
solve's start.

Either way the first solve is kept where no restart does better, and every restart's
black-box control steps are counted (as the batch runs them:
:func:`mjx_surrogate.control.effort.multistart_steps`).
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from mjx_surrogate.control import chunked
from mjx_surrogate.control.d2c import best_of, in_lockstep
from mjx_surrogate.control.effort import multistart_steps, steps_per_identification
from mjx_surrogate.control.ilqr import ILQRParams, StopReason
from mjx_surrogate.identification import sysid as sid
from mjx_surrogate.progress import NO_PROGRESS, ProgressMeter
from mjx_surrogate.systems.black_box import BlackBox
from mjx_surrogate.tasks import Task, half_ranges
from mjx_surrogate.timing import Timed


def spread_starts(task: Task, U0: jax.Array, key: jax.Array, n: int, scale: float = 1.0) -> jax.Array:
    """[n, T, nu]: U0 [T, nu] plus N(0, (scale half range)^2) per control (half range 1
    where unlimited), clipped to the limits."""
    lo, hi = np.asarray(task.u_min, float), np.asarray(task.u_max, float)
    half = jnp.asarray(half_ranges(lo, hi), U0.dtype)
    noise = scale * half * jax.random.normal(key, (n, *U0.shape), U0.dtype)
    return jnp.clip(U0[None] + noise, jnp.asarray(lo, U0.dtype), jnp.asarray(hi, U0.dtype))


STALL_SPREAD = 0.25  # of each actuator's half range, around a stalled solve's start


class RestartKind(NamedTuple):
    """Which first solve is restarted (its ``verdict``), how far the starts spread around its
    start (``scale`` x half range), and what the record says (``why``, ``spread``)."""

    verdict: str
    scale: float
    why: str
    spread: str


STATIONARY = RestartKind(
    "stationary",
    1.0,
    "the first solve was stationary",
    "the stationary start + N(0, half range^2) per control, clipped",
)
STALLED = RestartKind(
    "stalled",
    STALL_SPREAD,
    "the first solve stalled",
    f"the stalled solve's start + N(0, ({STALL_SPREAD:g} half range)^2) per control, clipped",
)


def restart_after(
    kind: RestartKind,
    system: BlackBox,
    task: Task,
    timed: Timed,
    U0: jax.Array,
    key: jax.Array,
    params: ILQRParams,
    sysid: sid.SysIdParams,
    n: int,
    progress: ProgressMeter = NO_PROGRESS,
) -> tuple[Timed, jax.Array, dict | None]:
    """(the solve to keep, its start, what the restart did or None): unchanged unless the
    D2C solve ``timed.out`` from U0 ended with ``kind.verdict`` and ``n`` > 0; then the best
    of ``n`` restarts around U0 (:func:`spread_starts` at ``kind.scale``, keys from ``key``)
    where it costs less than the first."""
    if n == 0 or StopReason(int(timed.out.stop_reason)).verdict != kind.verdict:
        return timed, U0, None
    first = timed.out
    k_starts, k_solve = jax.random.split(key)
    U0s = spread_starts(task, U0, k_starts, n, kind.scale)
    multi = restart_solves(system, task, U0s, k_solve, params, sysid, progress)
    ms = multi.out
    per_id = steps_per_identification(sysid, task.T, system.nu)
    i, best = int(ms.best_index), float(ms.costs[int(ms.best_index)])
    better = bool(np.isfinite(best) and best < float(first.cost))
    statuses = [StopReason(int(r)).verdict for r in np.asarray(ms.stop_reasons)]
    info = {
        "why": kind.why,
        "n_starts": int(np.asarray(ms.costs).shape[0]),  # fewer than n where a stop ended them
        "n_asked": n,
        "start_spread": kind.spread,
        "first_cost": float(first.cost),
        "costs": [float(c) for c in np.asarray(ms.costs)],
        "statuses": statuses,
        "simulated_steps": multistart_steps(
            np.asarray(ms.iterations),
            np.asarray(ms.identified),
            task.T,
            params.n_alphas,
            per_id,
            sid.fine_params(sysid) is not None,
            in_lockstep(system),
        ),
        "kept": f"restart {i}" if better else "the first solve (no restart cost less)",
    }
    total = Timed(ms.best if better else first, timed.compile_s + multi.compile_s, timed.run_s + multi.run_s)
    return total, (U0s[i] if better else U0), info


restart_stationary = functools.partial(restart_after, STATIONARY)
restart_stalled = functools.partial(restart_after, STALLED)


def restart_solves(
    system: BlackBox,
    task: Task,
    U0s: jax.Array,
    key: jax.Array,
    params: ILQRParams,
    sysid: sid.SysIdParams,
    progress: ProgressMeter = NO_PROGRESS,
) -> Timed:
    """D2C from each of U0s [n, T, nu] (keys split from ``key`` as a multi-start solve splits
    them): :class:`~mjx_surrogate.control.d2c.MultiStart` timed. A traced black box runs them
    as one batch; one stepped on the host runs them one after another anyway
    (:func:`~mjx_surrogate.control.d2c.in_lockstep`), so there each is the single start's
    solve, whose programs the first solve compiled (dm_control's humanoid at XLA's
    optimisation level 0: 30.0 s for four against 2.6 s compile + 33.3 s run as one
    multi-start program). A stop request ends
    the loop; the restarts finished by then are judged."""
    if in_lockstep(system):
        return chunked.solve(system, task, U0s, key, params, sysid, "d2c", progress)
    runs = []
    for U0_i, k_i in zip(U0s, jax.random.split(key, U0s.shape[0])):
        runs.append(chunked.solve(system, task, U0_i, k_i, params, sysid, "d2c", progress))
        if StopReason(int(runs[-1].out.stop_reason)) == StopReason.INTERRUPTED:
            break
    stacked = jax.tree.map(lambda *a: jnp.stack(a), *[r.out for r in runs])
    compile_s, run_s = sum(r.compile_s for r in runs), sum(r.run_s for r in runs)
    return Timed(best_of(stacked), compile_s, run_s)
