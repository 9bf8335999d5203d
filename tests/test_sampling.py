"""Sampling planners (mjx_surrogate/control/mpc_sampling.py, sampling_rules.py, splines.py)
against closed forms: splines read as matrices, each rule's update, the episode's
plan between replans, and the black-box calls counted."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mjx_surrogate.control import mpc, mpc_sampling, splines
from mjx_surrogate.control.ilqr import ILQRParams
from mjx_surrogate.control.mpc_sampling import SamplingSettings, hyper
from mjx_surrogate.control.sampling_rules import RULES
from mjx_surrogate.identification.sysid import SysIdParams
from mjx_surrogate.systems.function import from_jax, from_numpy
from mjx_surrogate.tasks import make_task

A = np.array([[1.0, 0.1], [0.0, 1.0]])  # a double integrator, dt 0.1
B = np.array([[0.005], [0.1]])
H, N = 10, 30


def _linear():
    A_, B_ = jnp.asarray(A), jnp.asarray(B)
    return from_jax(lambda x, u: A_ @ x + B_ @ u, 2, 1, 0.1)


def _task(limit=None):
    lo, hi = (None, None) if limit is None else ([-limit], [limit])
    Q, Q_f, R = np.diag([1.0, 0.1]), np.diag([10.0, 1.0]), np.diag([0.01])
    return make_task((1.0, 0.0), (0.0, 0.0), Q, Q_f, R, H, lo, hi)


def test_spline_bases_are_the_splines_they_name():
    """zero: the last knot at or before t; linear: np.interp inside, the end segments
    extended; cubic through 4 knots: the one cubic polynomial through them (np.polyfit),
    extrapolated too; one knot: a constant."""
    tau = np.array([0.0, 2.0, 5.0, 9.0])
    y = np.array([0.3, -1.0, 0.5, 2.0])
    t = np.linspace(-1.0, 12.0, 27)
    zero = splines.basis("zero", tau, t) @ y
    expect = [y[max(0, np.searchsorted(tau, ti, side="right") - 1)] for ti in t]
    np.testing.assert_array_equal(zero, expect)
    lin = splines.basis("linear", tau, t) @ y
    inside = (t >= 0) & (t <= 9)
    np.testing.assert_allclose(lin[inside], np.interp(t[inside], tau, y), atol=1e-12)
    slope = (y[-1] - y[-2]) / (tau[-1] - tau[-2])
    np.testing.assert_allclose(lin[t > 9], y[-1] + slope * (t[t > 9] - 9), atol=1e-12)
    cubic = splines.basis("cubic", tau, t) @ y
    np.testing.assert_allclose(cubic, np.polyval(np.polyfit(tau, y, 3), t), atol=1e-9)
    np.testing.assert_array_equal(splines.basis("cubic", tau[:1], t), np.ones((len(t), 1)))
    np.testing.assert_array_equal(splines.knot_times(50, 11), np.linspace(0, 50, 11))
    with pytest.raises(ValueError, match="spline kind"):
        splines.basis("quadratic", tau, t)


def test_a_cubic_plan_moved_on_is_the_same_cubic_later():
    """Four cubic knots hold one cubic polynomial p; the plan r steps later is p(t + r) at
    every step, and a plan that is a spline is its own least-squares fit."""
    s = SamplingSettings(knots=4, spline="cubic")
    p = np.array([0.002, -0.03, 0.1, 0.5])
    U0 = jnp.asarray(np.polyval(p, np.arange(H))[:, None])
    plan = mpc_sampling.first_spline_plan(U0, s, 1.0)
    np.testing.assert_allclose(np.asarray(plan.U), np.asarray(U0), atol=1e-10)
    later = mpc_sampling.moved_on(plan, 3, s)
    np.testing.assert_allclose(np.asarray(later.U)[:, 0], np.polyval(p, np.arange(H) + 3), atol=1e-10)
    held = mpc_sampling.moved_on(plan, 3, s._replace(spline="zero"))  # beyond the end: the last knot
    assert np.asarray(held.mean)[-1] == np.asarray(plan.mean)[-1]


def test_a_plan_on_an_actuator_without_limits_holds_its_end_past_the_last_knot():
    """A limited actuator's cubic plan extends its end polynomial past the last knot, as
    hydrax's do (the clip bounds it); an unlimited one's holds the spline's end value, so
    the extension cannot compound from replan to replan. On the device and on the host."""
    s = SamplingSettings(knots=4, spline="cubic")
    p = np.array([0.002, -0.03, 0.1, 0.5])
    u = np.polyval(p, np.arange(H))
    plan = mpc_sampling.first_spline_plan(jnp.asarray(np.stack([u, -u], 1)), s, 1.0)
    free = jnp.array([False, True])  # the first actuator limited, the second not
    later = mpc_sampling.moved_on(plan, 3, s, free)
    extended = mpc_sampling.moved_on(plan, 3, s)
    end = float(np.polyval(p, H))  # the last knot's time is the horizon's end, step H
    np.testing.assert_allclose(np.asarray(later.mean)[:, 0], np.asarray(extended.mean)[:, 0])
    np.testing.assert_allclose(np.asarray(later.mean)[-1, 1], -end, atol=1e-10)
    assert abs(float(extended.mean[-1, 1]) + end) > 1e-3  # the extension would differ there
    np.testing.assert_allclose(np.asarray(later.mean)[:-1, 1], np.asarray(extended.mean)[:-1, 1])
    host = mpc_sampling.SplinePlan(*(np.asarray(a) for a in plan))
    on_host = mpc_sampling.moved_on_host(host, 3, s, np.asarray(free))
    np.testing.assert_allclose(on_host.mean, np.asarray(later.mean), atol=1e-12)
    np.testing.assert_allclose(on_host.U, np.asarray(later.U), atol=1e-12)
    limits = ([-1.0, -np.inf], [1.0, 2.0])  # the second unbounded below
    task = make_task(np.zeros(1), np.zeros(1), np.eye(1), np.eye(1), np.eye(2), H, *limits)
    assert np.asarray(mpc_sampling.unbounded(task)).tolist() == [False, True]


def test_each_rule_updates_as_its_algorithm_says():
    """Predictive sampling keeps the mean as a draw and moves to the cheapest; MPPI to the
    softmax(-J / lambda) average; CEM to the elites' mean and spread, floored."""
    key = jax.random.key(0)
    mean, spread = jnp.zeros((3, 1)), jnp.full((3, 1), 0.5)
    h = hyper(0.5, 2.0, 0.2)
    ps = RULES["predictive_sampling"].sample(key, mean, spread, 8, 0, h)
    assert ps.shape == (8, 3, 1) and np.all(np.asarray(ps[0]) == 0) and np.all(np.asarray(ps[1:]) != 0)
    knots = jax.random.normal(jax.random.key(1), (6, 3, 1))
    J = jnp.array([3.0, 1.0, 4.0, 0.5, 9.0, 2.0])
    best, _ = RULES["predictive_sampling"].update(knots, J, mean, spread, 1, h)
    np.testing.assert_array_equal(np.asarray(best), np.asarray(knots[3]))
    avg, kept = RULES["mppi"].update(knots, J, mean, spread, 1, h)
    w = np.exp(-np.asarray(J) / 2.0)
    np.testing.assert_allclose(
        np.asarray(avg), np.einsum("s,skj->kj", w / w.sum(), np.asarray(knots)), atol=1e-12
    )
    assert kept is spread
    m, sd = RULES["cem"].update(knots, J, mean, spread, 3, h)
    elites = np.asarray(knots)[[3, 1, 5]]
    np.testing.assert_allclose(np.asarray(m), elites.mean(0), atol=1e-12)
    np.testing.assert_allclose(np.asarray(sd), np.maximum(elites.std(0), 0.2), atol=1e-12)
    draws = RULES["cem"].sample(key, mean, jnp.full((3, 1), 1e-9), 100, 40, h)  # 40 at the start spread
    assert np.abs(np.asarray(draws[:60])).max() < 1e-7 and 0.3 < np.asarray(draws[60:]).std() < 0.7


@pytest.mark.parametrize("replan_every", [1, 3])
def test_zero_spread_applies_the_first_plan_moved_on_between_replans(replan_every):
    """sigma 0: every draw is the mean, so the episode applies U0 step by step (its last
    control held once U0 runs out), replanning at every step or every third one."""
    U0 = jnp.asarray(np.sin(np.arange(H))[:, None])
    for rule in ("predictive_sampling", "cem"):
        r = mpc_sampling.sampling_mpc(
            _linear(),
            _task(),
            U0,
            key=jax.random.key(0),
            steps=N,
            settings=SamplingSettings(rule, 8),
            hyper=hyper(0.0),
            replan_every=replan_every,
        )
        assert r.plan_cost.shape == (N // replan_every,)
        applied = np.concatenate([np.asarray(U0), np.repeat(np.asarray(U0[-1:]), N - H, axis=0)])
        # predictive sampling keeps the mean itself; CEM averages identical elites (round-off)
        np.testing.assert_allclose(np.asarray(r.U), applied, rtol=0, atol=0 if rule != "cem" else 1e-15)
        X = [np.array([1.0, 0.0])]
        for u in applied:
            X.append(A @ X[-1] + B @ u)
        np.testing.assert_allclose(np.asarray(r.X), np.array(X), atol=1e-12)


def test_between_replans_the_plant_gets_the_splines_controls():
    """Knotted plans: the controls applied between two replans are the plan's spline read
    at those steps, so with linear knots and no spread they continue U0's line (on a
    limited actuator; an unlimited one's plans hold their end past the last knot)."""
    U0 = jnp.asarray((0.1 * np.arange(H) - 0.3)[:, None])
    s = SamplingSettings(samples=4, knots=3, spline="linear")
    key = jax.random.key(0)
    r = mpc_sampling.sampling_mpc(
        _linear(), _task(10.0), U0, key=key, steps=9, settings=s, hyper=hyper(0.0), replan_every=3
    )
    np.testing.assert_allclose(np.asarray(r.U)[:, 0], 0.1 * np.arange(9) - 0.3, atol=1e-12)


@pytest.mark.slow
def test_every_rule_beats_no_control_and_none_beats_the_lqr():
    """Within limits (the knots are clipped to them, which also bounds a cubic's extension
    beyond the horizon, as hydrax clips its knots)."""
    system, task, U0 = _linear(), _task(3.0), jnp.zeros((H, 1))
    idle = mpc_sampling.sampling_mpc(
        system,
        task,
        U0,
        key=jax.random.key(4),
        steps=N,
        settings=SamplingSettings(samples=2),
        hyper=hyper(0.0),
    )
    lqr = mpc.receding_horizon(
        system,
        task,
        U0,
        key=jax.random.key(0),
        steps=N,
        params=ILQRParams(max_iter=3),
        sysid=SysIdParams(n_samples=6),
        controller="jacfwd",
    )
    for rule in RULES:
        for knots, spline in ((0, "zero"), (4, "cubic")):
            s = SamplingSettings(rule, 64, knots, spline, iterations=2)
            r = mpc_sampling.sampling_mpc(
                system, task, U0, key=jax.random.key(4), steps=N, settings=s, hyper=hyper(2.0, 1.0, 0.1)
            )
            assert float(lqr.cost) <= float(r.cost) < 0.5 * float(idle.cost), (rule, knots, float(r.cost))


def test_black_box_steps_are_the_calls_the_black_box_received():
    calls = []

    def step(x, u):
        calls.append(len(x))
        return x @ A.T + u @ B.T

    system = from_numpy(step, 2, 1, 0.1, vectorized=True)
    for rule, iterations in (("predictive_sampling", 1), ("mppi", 1), ("cem", 3)):
        calls.clear()
        s = SamplingSettings(rule, 16, iterations=iterations)
        mpc_sampling.sampling_mpc(
            system, _task(), jnp.zeros((H, 1)), key=jax.random.key(0), steps=5, settings=s, hyper=hyper(1.0)
        )
        assert sum(calls) == 5 + 5 * mpc_sampling.black_box_steps(s, H), (rule, sum(calls))


def test_a_planners_own_settings_override_the_shared_ones_in_range_units():
    """The spread in each actuator's half range where both limits are finite (control
    units otherwise); the planner's own samples, knots and temperature over mpc's; the
    matched budget split over the iterations."""
    import dataclasses
    from types import SimpleNamespace

    from mjx_surrogate.control.sampling_planners import SETTINGS, resolved, spread_scale
    from mjx_surrogate.runs.config import Config

    np.testing.assert_array_equal(
        spread_scale([-1.0, -np.inf, 0.0], [3.0, 1.0, 0.5], "range"), [2.0, 1.0, 0.25]
    )
    np.testing.assert_array_equal(spread_scale([-1.0], [3.0], "control"), [1.0])
    task = make_task((1.0, 0.0), (0.0, 0.0), np.eye(2), np.eye(2), np.eye(1), H, [-2.0], [4.0])
    cfg = Config()
    cfg = dataclasses.replace(cfg, mpc=dataclasses.replace(cfg.mpc, sampling_sigma=0.5, sampling_knots=3))
    own = {
        "mppi": dataclasses.replace(SETTINGS["mppi"], temperature=0.2, iterations=2, spline="cubic"),
        "cem": dataclasses.replace(
            SETTINGS["cem"], samples=40, knots=0, sigma_units="control", explore_fraction=0.25
        ),
    }
    c = SimpleNamespace(
        config=cfg,
        planner_settings=own,
        samples=30,
        samples_matched=True,
        plan_task=task,
        system=_linear(),
        U0=jnp.zeros((H, 1)),
    )
    s, h, _ = resolved(c, "mppi")
    assert (s.samples, s.knots, s.spline, s.iterations) == (15, 3, "cubic", 2)  # 30 over 2 iterations
    assert float(h.sigma[0]) == 0.5 * 3.0 and float(h.temperature) == 0.2  # half range 3
    s, h, _ = resolved(c, "cem")
    assert (s.samples, s.knots, s.explore, s.elites) == (40, 0, 10, 3) and float(h.sigma[0]) == 0.5
    s, h, _ = resolved(c, "predictive_sampling")  # no settings of its own: the defaults, in range units
    assert (s.samples, s.knots, s.spline) == (30, 3, "zero") and float(h.sigma[0]) == 1.5


def test_a_planner_at_its_own_samples_has_a_row_at_d2c_mpcs_budget_beside_it():
    """``budget_row``: the planner's own settings at D2C-MPC's budget (split over its
    iterations) as a second row, counted at its own samples; none without the budget, without
    the setting, or where both rows would draw the same samples."""
    import dataclasses
    from types import SimpleNamespace

    from experiments.mpc_study import _stems
    from mjx_surrogate.control.sampling_planners import SETTINGS, rows, sampling_episodes, sampling_steps
    from mjx_surrogate.runs.config import Config

    task = make_task((1.0, 0.0), (0.0, 0.0), np.eye(2), np.eye(2), np.eye(1), H, [-2.0], [4.0])
    cfg = Config()
    cfg = dataclasses.replace(cfg, mpc=dataclasses.replace(cfg.mpc, horizon=H))
    own = {
        "cem": dataclasses.replace(SETTINGS["cem"], samples=40, iterations=2, budget_row=True),
        "mppi": dataclasses.replace(SETTINGS["mppi"], samples=40),
        "predictive_sampling": dataclasses.replace(
            SETTINGS["predictive_sampling"], samples=30, budget_row=True
        ),
    }
    base = dict(config=cfg, planner_settings=own, samples=30, plan_task=task, system=_linear())
    c = SimpleNamespace(**base, samples_matched=True, U0=jnp.zeros((H, 1)), replan_every=1)
    found = rows(c, "cem")
    assert list(found) == ["CEM (S=15, 2 iterations)", "CEM (S=40, 2 iterations)"]
    assert [v[0].iterations for v in found.values()] == [2, 2]
    assert list(sampling_episodes("cem")(c)) == list(found)
    assert list(rows(c, "mppi")) == ["MPPI (S=40)"]  # no budget_row
    assert list(rows(c, "predictive_sampling")) == ["predictive sampling (S=30)"]  # the same samples
    alone = SimpleNamespace(**base, samples_matched=False, U0=jnp.zeros((H, 1)), replan_every=1)
    assert list(rows(alone, "cem")) == ["CEM (S=40, 2 iterations)"]  # no D2C-MPC budget to match
    steps = sampling_steps("cem")
    for row, S in (("CEM (S=15, 2 iterations)", 15), ("CEM (S=40, 2 iterations)", 40)):
        counted = steps(SimpleNamespace(**vars(c), row=row), None)
        assert counted == mpc_sampling.black_box_steps(found[row][0], H) == 2 * S * H
    assert _stems(list(found)) == {"CEM (S=15, 2 iterations)": "CEM", "CEM (S=40, 2 iterations)": "CEM_1"}
    labels = ["SINDy cubic_trig MPC", "MLP MPC", "SINDy cubic_trig MPC refitted online"]
    assert _stems(labels) == {x: x.replace(" ", "_") for x in labels}  # as before: runs resume


def test_the_hybrids_proposals_are_the_warm_start_and_smooth_draws_around_it():
    from mjx_surrogate.control.mpc_hybrid import proposals

    U = jnp.asarray(np.linspace(-1, 1, H)[:, None])
    P = np.asarray(proposals(jax.random.key(0), U, 6, 3, "zero", 0.5, -0.8, 0.8))
    assert P.shape == (6, H, 1)
    np.testing.assert_array_equal(P[0], np.asarray(U))  # the warm start itself, unclipped
    tau = splines.knot_times(H, 3)
    z = np.asarray(jax.random.normal(jax.random.key(0), (5, 3, 1)))
    expect = np.clip(
        np.asarray(U) + 0.5 * np.einsum("tk,skj->stj", splines.basis("zero", tau, np.arange(H)), z), -0.8, 0.8
    )
    np.testing.assert_allclose(P[1:], expect, atol=1e-12)


@pytest.mark.slow
def test_the_hybrid_with_no_spread_is_d2c_mpc_on_a_linear_system():
    """sigma 0: every draw is the warm start, so each replan is D2C-MPC's (the linear map
    identified to round-off): the same closed loop."""
    from mjx_surrogate.control.mpc_hybrid import hybrid_mpc

    params, sysid = ILQRParams(max_iter=3), SysIdParams(n_samples=6)
    task, U0 = _task(), jnp.zeros((H, 1))
    d2c = mpc.receding_horizon(
        _linear(), task, U0, key=jax.random.key(0), steps=N, params=params, sysid=sysid
    )
    hyb = hybrid_mpc(
        _linear(),
        task,
        U0,
        key=jax.random.key(0),
        steps=N,
        params=params,
        sysid=sysid,
        sigma=jnp.asarray(0.0),
        n_samples=4,
        knots=2,
    )
    np.testing.assert_allclose(np.asarray(hyb.X), np.asarray(d2c.X), atol=1e-8)
