"""Solves driven from the host in compiled chunks of iterations, with no host callback.

:func:`mjx_surrogate.control.d2c.solve_d2c` runs a whole solve as one program; its progress meter
is a host callback inside the loop, and JAX keeps no program with a host callback in its
persistent compilation cache. Here the same solve is two programs, ``start`` (the initial
rollout) and ``advance`` (iterate up to a given iteration count), and the host loops over
``advance`` in chunks of about ``chunk_s`` seconds: between chunks it updates the progress
bar and checks for a stop request (SIGINT/SIGTERM), which ends the solve with
``StopReason.INTERRUPTED`` and its best iterate. On the MJX backend neither program holds a
callback, and the native backend's simulator is a named host call that the cache keeps
(:mod:`mjx_surrogate.systems.host_call`), so a second run of the same problem loads both
from the cache (:mod:`mjx_surrogate.runtime`).

The iterates are the ones of the one-program solve with the same inputs: the loop body is
the same function. ``U0`` [T, nu] gives one solve (an :class:`~mjx_surrogate.control.ilqr.ILQRResult`),
``U0`` [S, T, nu] a multi-start solve (a :class:`~mjx_surrogate.control.d2c.MultiStart`, starts
spread over ``system.mesh`` as in :func:`~mjx_surrogate.control.d2c.solve_multistart`).

Over several processes (:mod:`jax.distributed`) :func:`solve` runs the one-program solve
(its meter polled from inside, as before): a host loop there would need every process to
agree on each chunk's length and stop, and a two-process test of that hung once under load
on 2 cores (docs/performance.md), so it is left for later.
"""

from __future__ import annotations

import functools
import time

import jax
import jax.numpy as jnp
import numpy as np

from mjx_surrogate import progress as progress_lib
from mjx_surrogate import sharding
from mjx_surrogate.control import d2c
from mjx_surrogate.control.d2c import best_of, check_oracle, over_starts, problem
from mjx_surrogate.control.ilqr import (
    ILQRParams,
    SolveState,
    StopReason,
    ilqr_advance,
    ilqr_init,
    ilqr_result,
)
from mjx_surrogate.identification import sysid as sid
from mjx_surrogate.systems.black_box import BlackBox
from mjx_surrogate.tasks import Task
from mjx_surrogate.timing import Timed, compile_then_run


def _init_one(system, task, U0, key, params, sysid, method) -> SolveState:
    return ilqr_init(problem(system, task, sysid, method), U0, params, key)


@functools.partial(jax.jit, static_argnames=("system", "method"))
def start(
    system: BlackBox,
    task: Task,
    U0: jax.Array,
    key: jax.Array,
    params: ILQRParams,
    sysid: sid.SysIdParams,
    method: str,
) -> tuple[SolveState, jax.Array]:
    """The state before the first iteration and its :func:`_summary`; U0 [S, T, nu] gives S
    states (batch axis first)."""
    if U0.ndim == 2:
        state = _init_one(system, task, U0, key, params, sysid, method)
        return state, _summary(state)
    keys = jax.random.split(key, U0.shape[0])  # as solve_multistart
    single = system.on_one_device()

    def starts(U0s, keys, task, params, sysid):
        init = lambda u, k: _init_one(single, task, u, k, params, sysid, method)  # noqa: E731
        return over_starts(single, init, U0s, keys)

    state = sharding.map_batch(starts, system.mesh, U0, keys, rest=(task, params, sysid))
    return state, _summary(state)


def _summary(state: SolveState) -> jax.Array:
    """[4]: any solve running, the most iterations done, the lowest cost, the lowest mu."""
    s = state.solver
    J = jnp.where(jnp.isfinite(s.cost), s.cost, jnp.inf)
    running = jnp.any(s.stop_reason == StopReason.RUNNING)
    it = jnp.max(s.iterations).astype(J.dtype)
    return jnp.stack([running.astype(J.dtype), it, jnp.min(J), jnp.min(s.mu)])


@functools.partial(jax.jit, static_argnames=("system", "method"), donate_argnames=("state",))
def advance(
    system: BlackBox,
    task: Task,
    state: SolveState,
    until: jax.Array,
    stop: jax.Array,
    params: ILQRParams,
    sysid: sid.SysIdParams,
    method: str,
) -> tuple[SolveState, jax.Array]:
    """Iterate every running solve until it stops or has done ``until`` iterations (``stop``:
    mark them interrupted instead); returns the new state and its :func:`_summary`."""
    if state.solver.X.ndim == 2:
        new = ilqr_advance(problem(system, task, sysid, method), state, params, until, stop)
        return new, _summary(new)
    single = system.on_one_device()

    def steps(states, task, until, stop, params, sysid):
        prob = problem(single, task, sysid, method)
        return over_starts(single, lambda s: ilqr_advance(prob, s, params, until, stop), states)

    new = sharding.map_batch(steps, system.mesh, state, rest=(task, until, stop, params, sysid))
    return new, _summary(new)


@jax.jit
def _result(state: SolveState):
    if state.solver.X.ndim == 2:
        return ilqr_result(state)
    return best_of(ilqr_result(state))


def solve(
    system: BlackBox,
    task: Task,
    U0: jax.Array,
    key: jax.Array,
    params: ILQRParams = ILQRParams(),
    sysid: sid.SysIdParams = sid.SysIdParams(),
    method: str = "d2c",
    progress: progress_lib.ProgressMeter = progress_lib.NO_PROGRESS,
    chunk_s: float = 0.5,
) -> Timed:
    """One solve ("d2c", "jacfwd" or "finite_difference", as :func:`mjx_surrogate.control.d2c.problem`)
    from U0 [T, nu] or [S, T, nu], driven in chunks of about ``chunk_s`` seconds; returns
    :class:`~mjx_surrogate.timing.Timed`: the result, the compile time of both programs and
    the run time. ``progress`` is updated and polled for stop requests between chunks."""
    if jax.process_count() > 1:
        return _one_program(system, task, U0, key, params, sysid, method, progress)
    t0 = time.perf_counter()
    start_c = start.lower(system, task, U0, key, params, sysid, method).compile(system.compiler_options)
    t1 = time.perf_counter()
    state, summary = jax.block_until_ready(start_c(task, U0, key, params, sysid))
    t2 = time.perf_counter()
    until, stop = jnp.asarray(0), jnp.asarray(False)
    advance_c = advance.lower(system, task, state, until, stop, params, sysid, method).compile(
        system.compiler_options
    )
    t3 = time.perf_counter()
    done, n = 0, 1
    while bool(np.asarray(summary)[0]):  # a solve is running
        requested = progress_lib.stop_polled(progress)
        tic = time.perf_counter()
        state, summary = advance_c(task, state, jnp.asarray(done + n), jnp.asarray(requested), params, sysid)
        summary = np.asarray(summary)
        elapsed = time.perf_counter() - tic
        it = int(summary[1])
        progress_lib.report(progress, it, summary[2], summary[3])
        # the next chunk: as many iterations as fit in chunk_s at this chunk's pace
        n = int(np.clip(chunk_s * max(it - done, 1) / max(elapsed, 1e-6), 1, max(params.max_iter, 1)))
        done = it
    out = jax.block_until_ready(_result(state))
    t4 = time.perf_counter()
    return Timed(out, (t1 - t0) + (t3 - t2), (t2 - t1) + (t4 - t3))


def _one_program(system, task, U0, key, params, sysid, method, progress) -> Timed:
    """The same solve as one program (:mod:`mjx_surrogate.control.d2c`), its meter polled inside."""
    kw = {"compiler_options": system.compiler_options}
    if U0.ndim == 3:
        kw["static_kwargs"], kw["dynamic_kwargs"] = {"method": method}, {"progress": progress}
        return compile_then_run(d2c.solve_multistart, (system,), (task, U0, key, params, sysid), **kw)
    if method == "d2c":
        return compile_then_run(d2c.solve_d2c, (system,), (task, U0, key, params, sysid, progress), **kw)
    return compile_then_run(
        d2c.solve_exact, (system,), (task, U0, params, progress), static_kwargs={"jacobians": method}, **kw
    )


def solve_exact(
    system: BlackBox,
    task: Task,
    U0: jax.Array,
    params: ILQRParams = ILQRParams(),
    progress: progress_lib.ProgressMeter = progress_lib.NO_PROGRESS,
    jacobians: str = "jacfwd",
    chunk_s: float = 0.5,
) -> Timed:
    """:func:`solve` of the exact-Jacobian oracle (:func:`mjx_surrogate.control.d2c.solve_exact`)."""
    method = check_oracle(jacobians)
    return solve(system, task, U0, jax.random.key(0), params, sid.SysIdParams(), method, progress, chunk_s)
