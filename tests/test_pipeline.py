"""Pipeline steps: the simulation count of a D2C solve against a counting black box."""

import types

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mjx_surrogate.control.ilqr import Cost, ILQRParams, ilqr
from mjx_surrogate.identification import sysid
from mjx_surrogate.runs import pipeline

A = np.array([[1.0, 0.1], [-0.3, 1.0]])
B = np.array([[0.0], [0.1]])


CASES = [("central_difference", 0, 1), ("forward_difference", 0, 1), ("forward_difference", 3, 1)]


@pytest.mark.slow
@pytest.mark.parametrize("scheme, reuse, every", CASES + [("central_difference", 0, 4)])
def test_simulation_curve_counts_every_black_box_step(scheme, reuse, every):
    calls = {"n": 0}

    def host_step(x, u):
        calls["n"] += int(np.prod(x.shape[:-1]))  # a batch of one-step simulations
        return np.einsum("ij,...j->...i", A, x) + np.einsum("ij,...j->...i", B, u)

    def step(x, u):
        out = jax.ShapeDtypeStruct(x.shape, x.dtype)
        return jax.pure_callback(host_step, out, x, u, vmap_method="broadcast_all")

    T, n_alphas = 15, 4
    p = sysid.SysIdParams(sigma_x=1e-4, sigma_u=1e-4, scheme=scheme, n_samples=6, every=every)
    linearize = sysid.ltv_linearize(types.SimpleNamespace(step=step), p)
    fine = sysid.ltv_linearize(types.SimpleNamespace(step=step), p.replace(every=1)) if every > 1 else None
    cost = Cost(lambda x, u: 0.5 * x @ x + 0.05 * u @ u, lambda x: 5.0 * x @ x)
    params = ILQRParams(
        max_iter=12,
        n_alphas=n_alphas,
        rel_tol=0.0,
        k_tol=0.0,
        reuse_tol=0.5,
        reuse_max=reuse,
        sysid_refine_tol=0.05,
    )
    inf = jnp.full(1, jnp.inf)
    res = ilqr(
        step,
        linearize,
        cost,
        jnp.array([1.0, 0.0]),
        jnp.zeros((T, 1)),
        -inf,
        inf,
        params,
        jax.random.key(0),
        linearize_fine=fine,
    )
    it = int(res.iterations)
    h = np.asarray(res.cost_history)[: it + 1]
    ident = np.asarray(res.identified)[:it]
    assert it >= 5 and not ident.all()  # iterations without an identification (rejected, reused)
    assert ident.any() and (np.any(h[1:] == h[:-1]) or reuse)
    if every > 1:  # the coarse model hands over to the fine one
        assert set(ident[ident > 0].tolist()) == {1, 2}
    per_id = pipeline.steps_per_identification(p, T)
    curve = pipeline.simulation_curve(res.identified, it, T, n_alphas, *per_id)
    assert curve.shape == (it + 1,) and curve[0] == T
    assert curve[-1] == calls["n"]
    m = pipeline.simulation_metrics(res, T, n_alphas, p)
    assert m["simulated_steps"] == calls["n"]
    first = np.nonzero(h <= h[-1] * 1.01)[0][0]
    assert m["simulations_to_optimum"]["1%"] == curve[first]
    assert m["simulations_to_optimum"]["1%"] <= m["simulations_to_optimum"]["0.1%"] <= calls["n"]


def _stationary_first_solve():
    """The hidden lever's D2C solve from zero controls, stationary; the call count reset."""
    from mjx_surrogate.control import chunked
    from mjx_surrogate.control.ilqr import StopReason

    system, task, calls = _hidden_lever()
    params = ILQRParams(max_iter=40)
    sid = sysid.SysIdParams(sigma_x=1e-4, sigma_u=1e-4, n_samples=10)
    U0 = jnp.zeros((30, 2))
    first = chunked.solve(system, task, U0, jax.random.key(0), params, sid)
    assert StopReason(int(first.out.stop_reason)) == StopReason.STATIONARY
    calls["n"] = 0
    return system, task, calls, params, sid, U0, first


def _hidden_lever():
    """x = [p, v, q]: q' = q + 0.1 u_1, v' = v + 0.1 u_0 q, p' = p + 0.1 v; the goal is on p
    alone. From zero controls q stays 0, so neither control moves the cost to first order:
    every local model says the start is stationary, while other starts reach the goal.
    Host NumPy, counting its one-step simulations."""
    from mjx_surrogate.systems.function import from_numpy
    from mjx_surrogate.tasks import make_task

    calls = {"n": 0}

    def step(x, u):  # [N, 3], [N, 2] -> [N, 3]
        calls["n"] += x.shape[0]
        p, v, q = x.T
        return np.stack([p + 0.1 * v, v + 0.1 * u[:, 0] * q, q + 0.1 * u[:, 1]], -1)

    system = from_numpy(step, 3, 2, 0.1, name="hidden_lever", vectorized=True, u_min=-2.0, u_max=2.0)
    Q_f = np.diag([100.0, 1.0, 0.0])
    task = make_task(
        np.zeros(3), np.array([1.0, 0.0, 0.0]), np.zeros((3, 3)), Q_f, 1e-3 * np.eye(2), 30, -2.0, 2.0
    )
    return system, task, calls


@pytest.mark.slow
def test_a_stationary_solve_is_followed_by_the_sampling_search_with_its_budget_counted(monkeypatch):
    """Where every local model is flat, CEM on the black box finds the hidden lever and D2C
    refines its plan to the goal; every black-box step of both is counted. Not run where it
    is not needed (the goal reached, a solve that moved, rounds 0), and the refined solve is
    kept only where it costs less."""
    from mjx_surrogate.runs import sampling_search as search

    system, task, calls, params, sid, U0, first = _stationary_first_solve()
    kept, U0_kept, info = search.search_then_refine(
        system, task, first, U0, jax.random.key(1), params, sid, 10, reached=False
    )
    assert info["search_steps"] + info["refined_steps"] == calls["n"] > 0
    assert info["kept"] == "the refined solve" and float(kept.out.cost) == info["refined_cost"]
    assert float(kept.out.cost) < 0.01 * float(first.out.cost)  # 50 -> reached
    assert not np.allclose(U0_kept, 0.0)  # the refined solve's start: the search's plan
    calls["n"] = 0
    for reached, rounds, solve in ((True, 10, first), (False, 0, first), (False, 10, kept)):
        same = search.search_then_refine(
            system, task, solve, U0, jax.random.key(1), params, sid, rounds, reached
        )
        assert same[0] is solve and same[2] is None
    assert calls["n"] == 0  # nothing simulated where it is not needed
    # a refined solve that costs more is not kept
    worse = first._replace(out=first.out._replace(cost=first.out.cost + 1.0))
    monkeypatch.setattr(search.chunked, "solve", lambda *a, **k: worse)
    kept, U0_kept, info = search.search_then_refine(
        system, task, first, U0, jax.random.key(1), params, sid, 2, False
    )
    assert kept.out is first.out and U0_kept is U0 and info["kept"].startswith("the stationary solve")


@pytest.mark.slow
def test_several_starts_that_all_end_stationary_are_followed_by_the_sampling_search():
    """Several starts (``solver.n_starts`` > 1): the cheapest start's solve, stationary, is
    followed by the sampling search as a single start's is, every start's cost kept; with
    the search off it stays stationary, and the spread restarts never follow several starts."""
    from mjx_surrogate.control.ilqr import StopReason

    system, task, calls = _hidden_lever()
    params = ILQRParams(max_iter=40)
    sid = sysid.SysIdParams(sigma_x=1e-4, sigma_u=1e-4, n_samples=10)
    U0s = jnp.zeros((2, 30, 2))
    off = pipeline.solve_from(system, task, U0s, jax.random.key(0), params, sid, 0, 4, 0.01)
    assert StopReason(int(off.timed.out.stop_reason)) == StopReason.STATIONARY
    assert off.search is None and off.restart is None and off.costs.shape == (2,)
    on = pipeline.solve_from(system, task, U0s, jax.random.key(0), params, sid, 10, 4, 0.01)
    assert on.search is not None and on.search["kept"] == "the refined solve", on.search
    assert on.restart is None and float(on.timed.out.cost) == on.search["refined_cost"]
    assert float(on.timed.out.cost) < 0.01 * float(off.timed.out.cost)  # 50 -> reached
    np.testing.assert_array_equal(on.costs, off.costs)  # the starts' own ends, as solved
    assert on.U0.shape == (30, 2) and not np.allclose(on.U0, 0.0)  # the search's plan


@pytest.mark.slow
def test_a_stationary_solve_is_restarted_from_spread_starts_with_their_budget_counted():
    from mjx_surrogate.control import chunked
    from mjx_surrogate.runs import restart

    system, task, calls, params, sid, U0, first = _stationary_first_solve()
    kept, U0_kept, info = restart.restart_stationary(
        system, task, first, U0, jax.random.key(1), params, sid, 4
    )
    assert info["simulated_steps"] == calls["n"] > 0  # every restart's black-box steps, counted
    assert info["n_starts"] == 4 and len(info["costs"]) == len(info["statuses"]) == 4
    assert info["kept"].startswith("restart") and float(kept.out.cost) == min(info["costs"])
    assert float(kept.out.cost) < 0.01 * float(first.out.cost)  # 50 -> reached: a restart moved it
    assert not np.allclose(U0_kept, 0.0)  # the kept solve's own start
    # off: unchanged, nothing simulated
    calls["n"] = 0
    same = restart.restart_stationary(system, task, first, U0, jax.random.key(1), params, sid, 0)
    assert same[0] is first and same[2] is None and calls["n"] == 0
    # a solve that is not stationary is not restarted
    moved = chunked.solve(system, task, U0_kept, jax.random.key(0), params, sid)
    assert (
        restart.restart_stationary(system, task, moved, U0_kept, jax.random.key(1), params, sid, 4)[2] is None
    )


@pytest.mark.slow
def test_a_stalled_solve_is_restarted_around_its_start_and_a_better_end_is_kept(monkeypatch):
    """A solve that ended stalled is solved again from starts spread around its start at a
    quarter of each actuator's half range, the cheapest kept where it costs less, every
    restart's black-box steps counted; no restart after any other verdict, with n = 0, or
    where no restart does better; :func:`pipeline.past_a_stall` runs it after a stall."""
    from mjx_surrogate.control.ilqr import StopReason
    from mjx_surrogate.runs import restart

    system, task, calls, params, sid, U0, first = _stationary_first_solve()
    # the hidden lever's stationary end, read as a stall (a contact model's is costly to make)
    stalled = first._replace(out=first.out._replace(stop_reason=jnp.asarray(int(StopReason.NO_DESCENT))))
    drawn = {}
    spread = restart.spread_starts

    def spy(task_, U0_, key, n, scale=1.0):
        drawn["starts"], drawn["scale"] = spread(task_, U0_, key, n, scale), scale
        return drawn["starts"]

    monkeypatch.setattr(restart, "spread_starts", spy)
    kept, U0_kept, info = restart.restart_stalled(
        system, task, stalled, U0, jax.random.key(1), params, sid, 4
    )
    assert drawn["scale"] == restart.STALL_SPREAD == 0.25
    assert 0.2 < float(np.std(np.asarray(drawn["starts"]))) < 0.8  # 0.25 x half range 2, clipped
    assert info["why"] == "the first solve stalled" and info["first_cost"] == float(first.out.cost)
    assert info["simulated_steps"] == calls["n"] > 0  # every restart's black-box steps, counted
    assert info["kept"].startswith("restart") and float(kept.out.cost) == min(info["costs"])
    assert float(kept.out.cost) < 0.01 * float(first.out.cost)  # 50 -> reached: a restart moved it
    np.testing.assert_array_equal(U0_kept, drawn["starts"][int(info["kept"].split()[1])])
    calls["n"] = 0
    for solve, n in ((stalled, 0), (first, 4), (kept, 4)):  # off; stationary; converged
        same = restart.restart_stalled(system, task, solve, U0, jax.random.key(1), params, sid, n)
        assert same[0] is solve and same[2] is None
    assert calls["n"] == 0  # nothing simulated where it is not needed
    # no restart cheaper than the stall: the stall kept, the restarts' record says so
    cheap = stalled._replace(out=stalled.out._replace(cost=jnp.asarray(-1.0)))
    same, U0_same, info = restart.restart_stalled(system, task, cheap, U0, jax.random.key(1), params, sid, 2)
    assert (
        same is not cheap and same.out is cheap.out and U0_same is U0 and info["kept"].startswith("the first")
    )
    # the pipeline's step after a stall: run with stall_restarts, not with 0
    args = (system, task, stalled, U0, jax.random.key(0), params, sid, 0, 0, 0.01)
    assert pipeline.past_a_stall(*args, stall_restarts=0)[2] is None
    after = pipeline.past_a_stall(*args, stall_restarts=2)[2]
    assert after is not None and after["why"] == "the first solve stalled" and after["n_starts"] == 2


@pytest.mark.slow
def test_restarts_on_a_host_black_box_are_the_single_starts_solves_and_match_the_batch():
    """On a black box stepped on the host the restarts run one after another as single-start
    solves (the first solve's programs); they end where the multi-start program ends."""
    from mjx_surrogate.control import chunked
    from mjx_surrogate.runs import restart

    system, task, calls, params, sid, U0, first = _stationary_first_solve()
    U0s = restart.spread_starts(task, U0, jax.random.key(3), 3)
    looped = restart.restart_solves(system, task, U0s, jax.random.key(4), params, sid)
    batch = chunked.solve(system, task, U0s, jax.random.key(4), params, sid)
    np.testing.assert_allclose(np.asarray(looped.out.costs), np.asarray(batch.out.costs), rtol=1e-6)
    np.testing.assert_array_equal(np.asarray(looped.out.iterations), np.asarray(batch.out.iterations))
    assert int(looped.out.best_index) == int(batch.out.best_index)
    assert looped.compile_s < batch.compile_s  # no new program: the single start's was compiled


def test_a_converged_solve_that_misses_its_goal_says_the_cost_stops_short():
    """The hint names the goal cost's share of the start's against the test's; a solve that
    reached its goal gets no hint, one that ran out of iterations the hint to give it room."""
    goal = {"reached": False, "goal_cost_start": 0.01, "goal_cost_final": 0.00354, "tolerance": 0.01}
    hint = pipeline.status_hint("converged", {"goal": goal})
    assert "goal cost 35.4 % of the start's; the test asks 1 %" in hint and "weigh the goal more" in hint
    assert pipeline.status_hint("converged", {"goal": {**goal, "reached": True}}) is None
    budget = pipeline.status_hint("max_iter", {"goal": goal, "iterations": 100})
    assert "ran out (100 iterations)" in budget and "goal is not reached" in budget
    assert "--solver.max_iter" in budget and "weigh the goal" not in budget
    reached = pipeline.status_hint("max_iter", {"goal": {**goal, "reached": True}, "iterations": 100})
    assert "--solver.max_iter" in reached and "goal is not reached" not in reached
    # a stall says what a stall is and what to try; after restarts that did not help, so
    stalled = pipeline.status_hint("stalled", {"goal": goal})
    assert "--solver.stall_restarts 8" in stalled and "restarts around its start" not in stalled
    after = {
        "why": "the first solve stalled",
        "n_starts": 4,
        "kept": "the first solve (no restart cost less)",
    }
    assert "4 restarts around its start found no lower cost" in pipeline.status_hint(
        "stalled", {"goal": goal, "restart": after}
    )
    kept = pipeline.status_hint("stalled", {"goal": goal, "restart": {**after, "kept": "restart 2"}})
    assert "the kept solve is restart 2 of 4" in kept and "no lower cost" not in kept
    cut = pipeline.status_hint(
        "stalled", {"goal": goal, "restart": {**after, "kept": "restart 0", "n_asked": 4, "n_starts": 2}}
    )
    assert "restart 0 of 2 (a stop request ended the other 2)" in cut


@pytest.mark.slow  # over 5 s: the fast tier's budget
def test_the_optimum_stage_of_the_other_kinds_honours_several_starts():
    """pipeline.optimum_stage (the offline optimum of the mpc, control, horizon, analysis
    and predict kinds) solves each of solver.n_starts starts and keeps the cheapest, as the
    d2c kind does: every start's cost recorded, the kept start stored as U0_star; one start
    records none."""
    import dataclasses

    from configs.smoke_d2c import CONFIG
    from mjx_surrogate.runs.resolution import resolve

    def stage(n):
        cfg = dataclasses.replace(CONFIG, solver=dataclasses.replace(CONFIG.solver, n_starts=n, max_iter=8))
        return pipeline.optimum_stage(resolve(cfg), jax.random.key(3))()

    m, arrays = stage(3)
    costs = m["multistart_costs"]
    assert len(costs) == 3 and m["cost_solver"] == pytest.approx(min(costs), rel=1e-12)
    assert len({round(c, 9) for c in costs}) == 3  # three distinct random starts
    assert arrays["U0_star"].shape == (10, 1)
    one, _ = stage(1)
    assert "multistart_costs" not in one


def _linear_quadratic():
    """x' = A x + B u (host NumPy, vectorized, counting its one-step simulations), a
    quadratic task of 12 steps from (1, 0)."""
    from mjx_surrogate.systems.function import from_numpy
    from mjx_surrogate.tasks import make_task

    calls = {"n": 0}

    def step(x, u):
        calls["n"] += x.shape[0]
        return x @ A.T + u @ B.T

    system = from_numpy(step, 2, 1, 0.1, name="lq", vectorized=True)
    Q = np.diag([1.0, 0.1])
    task = make_task(np.array([1.0, 0.0]), np.zeros(2), Q, 10 * Q, 0.01 * np.eye(1), 12, -np.inf, np.inf)
    return system, task, calls


@pytest.mark.slow
def test_the_receding_pass_replans_to_the_tasks_end_and_keeps_the_cheaper_solve(monkeypatch):
    """solver.receding_pass: on a linear-quadratic task, planned over the whole task, the
    pass's D2C-MPC closed loop, its plans ending at the task's end, costs the offline
    optimum (Bellman's principle), and D2C from it ends there too; the cheaper of the two
    solves is kept (a worse second solve leaves the first and its start); its black-box
    steps are the counted ones; H = 0 changes nothing."""
    from mjx_surrogate.control import chunked
    from mjx_surrogate.runs import receding_pass as rp

    system, task, calls = _linear_quadratic()
    params = ILQRParams(max_iter=20)
    sid = sysid.SysIdParams(sigma_x=1e-3, sigma_u=1e-3, n_samples=6)
    U0 = jnp.zeros((12, 1))
    first = chunked.solve(system, task, U0, jax.random.key(0), params, sid)
    first_count, J = calls["n"], float(first.out.cost)
    assert rp.receding_pass(system, task, first, U0, jax.random.key(0), params, sid, 0) == (first, U0, None)
    # over the whole task (H = 20 is cut to T = 12): every plan ends at the task's end
    calls["n"] = 0
    kept, U_kept, rec = rp.receding_pass(system, task, first, U0, jax.random.key(0), params, sid, 20)
    assert rec["closed_loop_steps"] + rec["refined_steps"] == calls["n"] > 0  # its budget, counted
    assert rec["first_steps"] == first_count
    assert rec["horizon"] == 12 and rec["first_cost"] == J
    assert rec["closed_loop_cost"] == pytest.approx(J, rel=1e-6)
    assert rec["refined_cost"] == pytest.approx(J, rel=1e-6)
    assert float(kept.out.cost) == min(J, rec["refined_cost"]) and U_kept.shape == (12, 1)
    worse = first._replace(out=first.out._replace(cost=jnp.asarray(J + 1.0)))
    monkeypatch.setattr(chunked, "solve", lambda *a, **k: worse)
    kept, U_kept, rec = rp.receding_pass(system, task, first, U0, jax.random.key(0), params, sid, 5)
    assert kept is first and U_kept is U0 and rec["kept"] == "the first solve"
    assert rec["refined_cost"] == J + 1.0


@pytest.mark.slow
def test_a_stop_request_ends_the_receding_pass_and_keeps_the_first_solve():
    """A stop request (SIGINT, SIGTERM) seen by the pass's closed loop ends it: the first
    solve and its start are kept, without the second solve, and the record says so."""
    from mjx_surrogate import progress
    from mjx_surrogate.control import chunked
    from mjx_surrogate.runs import receding_pass as rp

    system, task, _ = _linear_quadratic()
    params = ILQRParams(max_iter=20)
    sid = sysid.SysIdParams(sigma_x=1e-3, sigma_u=1e-3, n_samples=6)
    U0 = jnp.zeros((12, 1))
    first = chunked.solve(system, task, U0, jax.random.key(0), params, sid)
    with progress.meter("solve", 20, display=False) as pm:
        progress.request_stop()
        try:
            kept, U_kept, rec = rp.receding_pass(
                system, task, first, U0, jax.random.key(0), params, sid, 20, pm
            )
        finally:
            progress.clear_stop()
    assert kept is first and U_kept is U0
    assert rec["kept"] == "the first solve: stopped during the pass" and "refined_cost" not in rec
