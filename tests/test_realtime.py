"""The real-time loop (``mjx_surrogate.control.realtime``): plans applied by their time
stamps whatever the planner's latency, and, with a planner faster than the plant's period,
the synchronous episode's closed loop."""

import time

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mjx_surrogate.control import mpc, realtime
from mjx_surrogate.control.episode import Plan, first_plan

H, N = 60, 30


def _stamped_planner(delay: float):
    """A planner slower than the plant: its plan made at tick n asks for u = n + j at its row
    j, i.e. the tick itself, so that a plant that reads a plan by its stamp applies u_k = k."""
    calls = []

    def replan(x, plan, key, n):
        time.sleep(delay)
        calls.append(int(n))
        U = (n + np.arange(H, dtype=float))[:, None]
        return Plan(U, np.zeros((H + 1, 1)), np.zeros((H, 1, 1))), None

    return replan, calls


def test_the_plant_applies_the_newest_plan_at_the_row_of_its_own_tick():
    """With a planner 2.5 ticks slow, every tick applies its own index (the row k - stamp of
    the newest plan), plans arrive late, the planner replans from the newest measurement
    only (fewer replans than ticks), and the noise comes from the key."""
    dt = 0.01
    replan, calls = _stamped_planner(2.5 * dt)
    limits = (np.array([-1e9]), np.array([1e9]))
    r = realtime.run(
        replan,
        lambda x, u: x + u,
        np.zeros(1),
        Plan(np.zeros((H, 1)), np.zeros((H + 1, 1)), np.zeros((H, 1, 1))),
        dt=dt,
        steps=N,
        key=jax.random.key(0),
        limits=limits,
    )
    np.testing.assert_array_equal(r.U[:, 0], np.arange(N))
    np.testing.assert_array_equal(r.X[:, 0], np.concatenate([[0.0], np.cumsum(np.arange(N))]))
    lag = np.arange(N) - r.stamps
    assert np.all(lag >= 0) and lag.max() >= 2  # applied late, never before their stamp
    assert calls[0] == 0 and calls == sorted(set(calls)) and len(calls) < N
    assert len(r.replan_s) == len(calls) - 1  # the first plan is made before the clock starts
    noisy = realtime.run(
        replan, lambda x, u: x, np.zeros(1), first_plan(jnp.zeros((H, 1)), jnp.zeros(1)),
        dt=dt, steps=5, key=jax.random.key(3), limits=limits, process_noise=0.1,
    )  # fmt: skip
    w = [jax.random.normal(jax.random.split(k)[1], (1,)) for k in jax.random.split(jax.random.key(3), 5)]
    np.testing.assert_allclose(np.diff(noisy.X[:, 0]), 0.1 * np.concatenate(w), atol=1e-12)
    stepped = []  # a stop request, asked before every tick, ends the loop with the ticks done

    def plant(x, u):
        stepped.append(1)
        return x + u

    stopped = realtime.run(
        replan, plant, np.zeros(1), first_plan(jnp.zeros((H, 1)), jnp.zeros(1)), dt=dt, steps=N,
        key=jax.random.key(0), limits=limits, stop=lambda: len(stepped) >= 5,
    )  # fmt: skip
    assert stopped.U.shape == (5, 1) and stopped.X.shape == (6, 1) and len(stepped) == 5


@pytest.mark.slow  # over 5 s: the fast tier's budget
def test_a_planner_faster_than_the_plant_gives_the_synchronous_episode():
    """D2C-MPC on the native MuJoCo pendulum under process noise, the plant's clock slowed
    so that every replan ends before the next tick: every tick applies the plan of its own
    measurement, and the closed loop equals the synchronous episode's (the same keys, the
    same MuJoCo) to 1e-9."""
    from mjx_surrogate.control.ilqr import ILQRParams
    from mjx_surrogate.identification.sysid import SysIdParams
    from mjx_surrogate.runs.config import Config, SystemConfig, TaskConfig
    from mjx_surrogate.runs.resolution import resolve

    _, system, task = resolve(
        Config(system=SystemConfig(name="pendulum", backend="native"), task=TaskConfig(T=20))
    )
    params, sysid, steps = ILQRParams(max_iter=3), SysIdParams(n_samples=3), 15
    U0 = jnp.zeros((task.T, 1))
    sync = mpc.receding_horizon(
        system, task, U0, key=jax.random.key(0), steps=steps, params=params, sysid=sysid, process_noise=0.01
    )
    replan = jax.jit(mpc.d2c_replan(system, task, params, sysid))
    r = realtime.run(
        replan,
        realtime.native_plant(system.mj_model, system.substeps),
        np.asarray(task.x0),
        first_plan(U0, task.x0),
        dt=float(system.dt),
        steps=steps,
        key=jax.random.key(0),
        limits=(np.asarray(task.u_min), np.asarray(task.u_max)),
        process_noise=0.01,
        speed=0.5,
    )
    np.testing.assert_array_equal(r.stamps, np.arange(steps))
    np.testing.assert_allclose(r.X, np.asarray(sync.X), atol=1e-9)
    np.testing.assert_allclose(r.U, np.asarray(sync.U), atol=1e-9)


@pytest.mark.parametrize("knots,spline", [(0, "zero"), (4, "linear"), (5, "cubic")])
def test_a_spline_plan_moved_on_the_host_is_the_episodes_shift(knots, spline):
    """The wall-clock loop's NumPy shift of a sampling plan equals the episode's (JAX) for
    every shift up to past the horizon's end."""
    from mjx_surrogate.control import mpc_sampling as ms

    s = ms.SamplingSettings(knots=knots, spline=spline)
    rng = np.random.default_rng(0)
    plan = ms.first_spline_plan(jnp.asarray(rng.standard_normal((12, 2))), s, 0.5)
    host = jax.tree.map(np.asarray, plan)
    for r in (1, 3, 12, 15):
        want = ms.moved_on(plan, min(r, 12) if knots == 0 else r, s)
        got = ms.moved_on_host(host, r, s)
        for a, b in zip(got, want):
            np.testing.assert_allclose(a, np.asarray(b), atol=1e-12)
    assert not np.allclose(ms.moved_on_host(host, 1, s).U, host.U)  # it moves


@pytest.mark.slow  # over 5 s: the fast tier's budget
def test_a_sampling_planner_faster_than_the_plant_gives_the_synchronous_episode():
    """Predictive sampling over 4 linear knots on the native MuJoCo pendulum under process
    noise, replanning every 3rd tick, the clock slowed: the synchronous episode's closed loop
    to 1e-9 (its plans moved on by the host shift, its controls without gains)."""
    from mjx_surrogate.control import mpc_sampling as ms
    from mjx_surrogate.runs.config import Config, SystemConfig, TaskConfig
    from mjx_surrogate.runs.resolution import resolve

    _, system, task = resolve(
        Config(system=SystemConfig(name="pendulum", backend="native"), task=TaskConfig(T=20))
    )
    s, hyper, steps = ms.SamplingSettings(samples=16, knots=4, spline="linear"), ms.hyper(1.0), 15
    U0 = jnp.zeros((task.T, 1))
    key = jax.random.key(1)
    sync = ms.sampling_mpc(
        system, task, U0, key=key, steps=steps, settings=s, hyper=hyper, process_noise=0.01, replan_every=3
    )  # fmt: skip
    r = realtime.run(
        jax.jit(ms.replanner(system, task, s, hyper)),
        realtime.native_plant(system.mj_model, system.substeps),
        np.asarray(task.x0),
        ms.first_spline_plan(U0, s, hyper.sigma),
        dt=float(system.dt),
        steps=steps,
        key=key,
        limits=(np.asarray(task.u_min), np.asarray(task.u_max)),
        process_noise=0.01,
        speed=0.5,
        shift=lambda plan, n: ms.moved_on_host(plan, n, s, np.asarray(ms.unbounded(task))),
        replan_every=3,
    )
    np.testing.assert_array_equal(r.stamps, np.arange(steps) // 3 * 3)
    assert not np.any(realtime.lateness(r.stamps, 3)) and realtime.lateness(r.stamps - 1, 3).min() == 1
    assert np.abs(np.asarray(sync.X)[:, 0]).max() > 0.1  # the plans move the pendulum
    np.testing.assert_allclose(r.X, np.asarray(sync.X), atol=1e-9)
    np.testing.assert_allclose(r.U, np.asarray(sync.U), atol=1e-9)


@pytest.mark.slow  # over 5 s: the fast tier's budget
def test_the_mpc_kind_runs_its_planners_in_real_time_beside_their_synchronous_loops(tmp_path):
    """``mpc.realtime`` adds a "<planner> in real time" row per replanning planner and
    condition (D2C-MPC, predictive sampling), its episodes run in the wall-clock loop on the
    changed plant with the batch's keys: with the clock slowed so that no plan is late, the
    synchronous rows' closed loops and costs, written to the run folder and its table.
    One condition (the changed plant with noise 0.01: each episode's noise is drawn from its
    own key): the wall-clock loop runs its 4 episodes at a quarter of real time, 10 s."""
    import dataclasses
    import json
    import os

    from configs.smoke_mpc import CONFIG
    from experiments.run import run
    from mjx_surrogate.runs.realtime_rows import LABEL, label

    cfg = dataclasses.replace(
        CONFIG,
        mpc=dataclasses.replace(
            CONFIG.mpc,
            controllers=("d2c", "predictive_sampling"),
            realtime=True,
            realtime_speed=0.25,
            process_noise=(0.01,),
        ),
        experiment=dataclasses.replace(CONFIG.experiment, out_dir=str(tmp_path), video=False),
    )
    folder = run(cfg, name="realtime")
    with open(os.path.join(folder, "metrics.json")) as f:
        rows = json.load(f)["mpc_rows"]
    sampler = next(r["controller"] for r in rows if r["controller"].startswith("predictive sampling"))
    assert LABEL == label("D2C-MPC") and label(sampler) in {r["controller"] for r in rows}
    sync = [r for r in rows if r["controller"] in ("D2C-MPC", sampler)]
    late = [r for r in rows if r["controller"] in (LABEL, label(sampler))]
    assert len(sync) == len(late) == 2  # two planners, one plant, one noise level
    assert [label(r["controller"]) for r in sync] == [r["controller"] for r in late]
    arrays = np.load(os.path.join(folder, "arrays.npz"))
    for a, b in zip(sync, late):
        assert (a["plant"], a["process_noise"]) == (b["plant"], b["process_noise"])
        assert b["plans_late_ticks_max"] == 0 and b["plant_late_ticks"] == 0
        np.testing.assert_allclose(arrays[b["arrays"]["X"]], arrays[a["arrays"]["X"]], atol=1e-9)
        np.testing.assert_allclose(b["costs"], a["costs"], rtol=1e-9)
    with open(os.path.join(folder, "mpc_table.md")) as f:
        table = f.read()
    assert table.count(f"| {LABEL} |") == table.count(f"| {label(sampler)} |") == 1
