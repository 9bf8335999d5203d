"""Solves driven from the host in compiled chunks (mjx_surrogate.control.chunked): the iterates of
the one-program solve, no host callback in the programs, stop requests between chunks,
no recompilation."""

import os
import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mjx_surrogate import progress
from mjx_surrogate.control import chunked
from mjx_surrogate.control.d2c import in_lockstep, solve_d2c
from mjx_surrogate.control.ilqr import ILQRParams, StopReason
from mjx_surrogate.identification.sysid import SysIdParams
from mjx_surrogate.runs.config import Config, SystemConfig, TaskConfig
from mjx_surrogate.runs.pipeline import initial_controls
from mjx_surrogate.runs.resolution import resolve

P = ILQRParams(max_iter=40, rel_tol=1e-7, record_trajectories=True)
SID = SysIdParams(n_samples=6)


def _pendulum(backend):
    return resolve(
        Config(
            system=SystemConfig(name="pendulum", backend=backend),
            task=TaskConfig(preset="pendulum_d2c", T=30),
        )
    )


@pytest.fixture(scope="module")
def pendulum():
    """The native pendulum: chunking is the same on every backend, and the native step, a
    host call, compiles in about a fifth of the time MJX's does (the CLI's tests chunk MJX
    solves)."""
    _, system, task = _pendulum("native")
    U0 = initial_controls(jax.random.key(0), task.T, 1, "random", 0.1, None, task.x0.dtype)
    return system, task, U0


def assert_same(a, b):
    for name in a._fields:
        x, y = np.asarray(getattr(a, name)), np.asarray(getattr(b, name))
        assert np.array_equal(x, y, equal_nan=True), name


@pytest.mark.slow
def test_chunks_give_the_iterates_of_the_one_program_solve(pendulum):
    system, task, U0 = pendulum
    whole = solve_d2c(system, task, U0, jax.random.key(1), P, SID)
    # chunk_s tiny: a chunk of one iteration, then as many as the pace allows
    timed = chunked.solve(system, task, U0, jax.random.key(1), P, SID, chunk_s=1e-4)
    assert int(timed.out.iterations) > 3
    assert_same(whole, timed.out)
    assert timed.compile_s > 0 and timed.run_s > 0


@pytest.mark.slow
def test_multistart_chunks_are_the_single_solves_of_split_keys(pendulum):
    # solve_multistart's keys: jax.random.split(key, S), one per start
    system, task, U0 = pendulum
    U0s = jnp.stack([U0, 0.5 * U0, -U0])
    ms = chunked.solve(system, task, U0s, jax.random.key(2), P, SID, chunk_s=1e-4).out
    keys = jax.random.split(jax.random.key(2), 3)
    singles = [chunked.solve(system, task, u, k, P, SID).out for u, k in zip(U0s, keys)]
    # on a host black box the starts run one after another (d2c.over_starts), in a program
    # XLA compiles apart from the single solve's: equal to round-off, each its own iterations
    assert not in_lockstep(system)
    np.testing.assert_allclose(np.asarray(ms.costs), [float(r.cost) for r in singles], rtol=1e-12)
    np.testing.assert_array_equal(np.asarray(ms.iterations), [int(r.iterations) for r in singles])
    best = int(np.argmin([float(r.cost) for r in singles]))
    assert int(ms.best_index) == best
    assert int(ms.best.iterations) == int(singles[best].iterations)
    np.testing.assert_allclose(np.asarray(ms.best.U), np.asarray(singles[best].U), rtol=1e-9, atol=1e-12)


def test_the_oracles_jacobians_name_their_method(pendulum, monkeypatch):
    seen = []
    monkeypatch.setattr(chunked, "solve", lambda *a, **k: seen.append(a[6]))
    system, task, U0 = pendulum
    chunked.solve_exact(system, task, U0, P)
    chunked.solve_exact(system, task, U0, P, jacobians="finite_difference")
    assert seen == ["jacfwd", "finite_difference"]  # the method is the oracle's own name
    with pytest.raises(ValueError, match="'jacrev': valid: jacfwd, finite_difference"):
        chunked.solve_exact(system, task, U0, P, jacobians="jacrev")


def _callback_targets(lowered) -> list[str]:
    text = lowered.as_text()
    return [line for line in text.splitlines() if "callback" in line and "custom_call" in line]


def test_chunk_programs_hold_no_host_callback(pendulum):
    # JAX keeps no program with a host callback in its persistent cache; the one-program
    # solve polls its meter through one, the chunks must not.
    system, task, U0 = pendulum
    key = jax.random.key(0)
    with progress.meter("test", 10, display=False) as pm:
        assert _callback_targets(solve_d2c.lower(system, task, U0, key, P, SID, pm))
    state, _ = jax.eval_shape(lambda: chunked.start(system, task, U0, key, P, SID, "d2c"))  # no compile
    for lowered in (
        chunked.start.lower(system, task, U0, key, P, SID, "d2c"),
        chunked.advance.lower(system, task, state, jnp.asarray(1), jnp.asarray(False), P, SID, "d2c"),
    ):
        assert not _callback_targets(lowered)


@pytest.mark.slow
def test_a_stop_request_between_chunks_ends_interrupted_with_the_best_iterate(pendulum, monkeypatch):
    system, task, U0 = pendulum
    seen = []
    report = progress.report

    def report_then_stop(meter, iteration, cost, mu):
        seen.append(iteration)
        report(meter, iteration, cost, mu)
        if iteration >= 2:
            progress.request_stop()

    monkeypatch.setattr(progress, "report", report_then_stop)
    progress.clear_stop()
    try:
        with progress.meter("test", P.max_iter, display=False) as pm:
            out = chunked.solve(system, task, U0, jax.random.key(1), P, SID, progress=pm, chunk_s=1e-4).out
    finally:
        progress.clear_stop()
    whole = solve_d2c(system, task, U0, jax.random.key(1), P, SID)
    it = int(out.iterations)
    assert StopReason(int(out.stop_reason)) == StopReason.INTERRUPTED
    assert 2 <= it < int(whole.iterations) and seen[-1] == it
    # the iterate it stopped at is the one-program solve's at that iteration
    np.testing.assert_array_equal(np.asarray(out.X_history[it]), np.asarray(whole.X_history[it]))
    assert float(out.cost) == float(whole.cost_history[it]) < float(whole.cost_history[0])
    # a meter that is off never polls: the same solve runs to its end
    progress.request_stop()
    try:
        quiet = chunked.solve(system, task, U0, jax.random.key(1), P, SID, chunk_s=1e-4).out
    finally:
        progress.clear_stop()
    assert int(quiet.iterations) == int(whole.iterations)


def test_new_values_do_not_recompile_the_chunks(pendulum):
    system, task, U0 = pendulum
    chunked.solve(system, task, U0, jax.random.key(1), P, SID)
    n = chunked.advance._cache_size(), chunked.start._cache_size()
    p, sid = P.replace(mu_init=1e-4), SID.replace(sigma_u=2e-3)
    chunked.solve(system, task, U0 + 0.01, jax.random.key(3), p, sid)
    assert (chunked.advance._cache_size(), chunked.start._cache_size()) == n


@pytest.mark.slow
def test_native_programs_compile_with_the_systems_options_to_the_same_iterates(pendulum, monkeypatch):
    # Native-backend programs compile with System.compiler_options (a lower XLA backend
    # optimisation level), MJX ones with XLA's defaults; a level named in XLA_FLAGS (the
    # suite's, tests/conftest.py) holds for every program instead.
    assert pendulum[0].backend == "native" and _pendulum("mjx").system.compiler_options is None
    _, native, task = _pendulum("native")
    assert "xla_backend_optimization_level" in os.environ["XLA_FLAGS"] and native.compiler_options is None
    flags = re.sub(r"--xla_backend_optimization_level=\S+", "", os.environ["XLA_FLAGS"])
    monkeypatch.setenv("XLA_FLAGS", flags)  # as users run: options of the system's own
    task = task.replace(T=29)  # programs of their own, compiled in this test
    U0 = pendulum[2][:29]
    assert native.compiler_options == {"xla_backend_optimization_level": 1}
    seen = []
    compile_ = jax.stages.Lowered.compile

    def recording(self, compiler_options=None):
        seen.append(compiler_options)
        return compile_(self, compiler_options)

    monkeypatch.setattr(jax.stages.Lowered, "compile", recording)
    timed = chunked.solve(native, task, U0, jax.random.key(1), P, SID)
    assert seen == [native.compiler_options] * 2  # start and advance
    # the API's one-program solve compiles with the same options, so it gives the chunks'
    # iterates bit for bit (XLA's default level, as before system_jit, gave them to round-off)
    whole = solve_d2c(native, task, U0, jax.random.key(1), P, SID)
    assert int(timed.out.iterations) == int(whole.iterations) > 3
    np.testing.assert_array_equal(np.asarray(timed.out.X_history), np.asarray(whole.X_history))
    assert float(timed.out.cost) == float(whole.cost)
