"""The local model and its strategies (``mjx_surrogate.control.model_strategies``): when the
loop's model is identified, carried over by a secant update or kept; coarse models hand over
to fine ones; minima are declared on trusted models only. The solver's state holds none of
this; a strategy of one's own plugs in through ``Problem.strategy``."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mjx_surrogate.control import local_model as lm
from mjx_surrogate.control import model_strategies as ms
from mjx_surrogate.control.ilqr import ILQRParams, ILQRState, Problem, ilqr_advance, ilqr_init, ilqr_result
from mjx_surrogate.cost import Cost

T, nx, nu = 4, 2, 1
A_TRUE = jnp.broadcast_to(jnp.array([[1.0, 0.1], [0.0, 1.0]]), (T, nx, nx))
B_TRUE = jnp.broadcast_to(jnp.array([[0.0], [0.1]]), (T, nx, nu))
TRUE, FALSE = jnp.array(True), jnp.array(False)


def coarse(X, U, K, key):
    return A_TRUE, B_TRUE


def fine(X, U, K, key):
    return 2.0 * A_TRUE, 2.0 * B_TRUE


def make_problem(with_fine: bool = False) -> Problem:
    cost = Cost(lambda x, u: jnp.sum(x**2) + jnp.sum(u**2), lambda x: jnp.sum(x**2))
    lim = jnp.ones(nu)
    return Problem(lambda x, u: x, coarse, cost, jnp.zeros(nx), -lim, lim, None, fine if with_fine else None)


def nominal(scale: float = 0.0):
    return jnp.full((T + 1, nx), scale), jnp.full((T, nu), scale)


def outcome(accepted=True, ratio=1.0, at_minimum=False, stalled=False, before=1.0, after=0.5):
    return ms.StepOutcome(
        jnp.array(accepted),
        jnp.asarray(ratio),
        jnp.array(at_minimum),
        jnp.array(stalled),
        jnp.asarray(before),
        jnp.asarray(after),
    )


def make(problem, proposal, m=None, X_U=None):
    m = (
        lm.init_model(problem, ms.every_iteration(), *nominal(), jax.random.key(0), 3).model
        if m is None
        else m
    )
    X, U = nominal() if X_U is None else X_U
    return lm.make_model(problem, m, proposal, X, U, jnp.zeros((T, nu, nx)), jax.random.key(0))


def test_the_solver_state_holds_no_model_bookkeeping():
    assert set(ILQRState._fields) == {
        "X",
        "U",
        "K",
        "k",
        "cost",
        "mu",
        "iterations",
        "stop_reason",
        "cost_history",
        "X_history",
        "alpha_history",
    }
    from mjx_surrogate.control.ilqr import ILQRResult

    shared = set(ILQRState._fields) & set(ILQRResult._fields)
    assert shared == set(ILQRState._fields)  # the result names the state's fields as the state does


def test_every_iteration_identifies_when_the_nominal_moved_and_keeps_the_model_after_a_rejection():
    s = ms.every_iteration()
    st = s.init()
    assert bool(s.propose(st, ms.no_proposal()).identify)  # the first nominal
    st, report = s.update(st, ms.no_proposal(), outcome(accepted=False), ms.no_objection())
    assert not bool(s.propose(st, ms.no_proposal()).identify) and bool(report.trusted)
    st, _ = s.update(st, ms.no_proposal(), outcome(accepted=True), ms.no_objection())
    assert bool(s.propose(st, ms.no_proposal()).identify)


@pytest.mark.slow  # over 5 s: the fast tier's budget
def test_the_proposal_is_carried_out_identify_carry_or_keep():
    p = make_problem()
    m, how = make(p, ms.Proposal(TRUE, FALSE, FALSE))
    assert int(how) == lm.How.IDENTIFIED
    np.testing.assert_array_equal(m.A, A_TRUE)
    X1, U1 = nominal(0.5)
    carried, how = make(p, ms.Proposal(FALSE, TRUE, FALSE), m, (X1, U1))
    A_ref, B_ref = lm.secant_update(A_TRUE, B_TRUE, X1 - m.X, U1 - m.U)
    assert int(how) == lm.How.KEPT
    np.testing.assert_allclose(carried.A, A_ref, rtol=0, atol=0)
    np.testing.assert_allclose(carried.B, B_ref, rtol=0, atol=0)
    np.testing.assert_array_equal(carried.X, X1)  # the model now belongs to the new nominal
    kept, how = make(p, ms.Proposal(FALSE, FALSE, FALSE), m._replace(A=3.0 * A_TRUE))
    assert int(how) == lm.How.KEPT
    np.testing.assert_array_equal(kept.A, 3.0 * A_TRUE)


def test_reuse_carries_the_model_over_after_a_passed_step_and_distrusts_it():
    s = ms.chain(ms.every_iteration(), ms.secant_reuse(0.2, 2))
    st = s.init()
    p = s.propose(st, ms.no_proposal())
    st, r = s.update(st, p, outcome(ratio=1.1), ms.no_objection())
    assert bool(p.identify) and bool(r.trusted)  # the first model is identified
    p = s.propose(st, ms.no_proposal())
    assert not bool(p.identify) and bool(p.carry)  # passed: carried over
    st, r = s.update(st, p, outcome(ratio=1.1), ms.no_objection())
    assert not bool(r.trusted) and int(st[1].count) == 1  # no minimum on a carried-over model
    st_rejected, _ = s.update(st, s.propose(st, ms.no_proposal()), outcome(accepted=False), ms.no_objection())
    p = s.propose(st_rejected, ms.no_proposal())
    assert bool(p.identify) and not bool(p.carry)  # rejected on a carried model: identified afresh


def test_the_reuse_test_and_its_limit():
    s = ms.secant_reuse(0.2, 2)
    carry = ms.Proposal(FALSE, TRUE, FALSE)

    def ok(ratio, count=0, accepted=True, at_minimum=False):
        st = ms.ReuseState(FALSE, FALSE, jnp.asarray(count))
        return bool(s.update(st, carry, outcome(accepted, ratio, at_minimum), ms.no_objection())[0].ok)

    assert ok(1.1)
    assert not ok(1.3)  # the model's promise missed by more than tol
    assert not ok(1.1, count=1)  # max_reuse carried-over models in a row (this one is the 2nd)
    assert not ok(1.1, at_minimum=True)
    assert not ok(1.0, accepted=False)


def test_a_coarse_model_hands_over_to_the_fine_one_and_only_that_is_trusted():
    p = make_problem(with_fine=True)
    s = ms.chain(ms.every_iteration(), ms.coarse_then_fine(0.05, has_fine=True))
    st = s.init()
    prop = s.propose(st, ms.no_proposal())
    m, how = make(p, prop)
    assert int(how) == lm.How.IDENTIFIED
    np.testing.assert_array_equal(m.A, A_TRUE)  # the coarse model
    go_on, r = s.update(st, prop, outcome(before=1.0, after=0.5), ms.no_objection())
    assert not bool(r.handover) and not bool(r.trusted) and not bool(r.fine) and not bool(go_on[1].fine)
    for o in (outcome(at_minimum=True), outcome(stalled=True), outcome(before=1.0, after=0.96)):
        st_next, r = s.update(st, prop, o, ms.no_objection())  # a minimum, a stall, a small gain
        assert bool(r.handover) and bool(st_next[1].fine)
    rejected = st_next[0]._replace(fresh=FALSE)  # even on the same nominal, the fine model is identified
    prop = s.propose((rejected, st_next[1]), ms.no_proposal())
    m_fine, how = make(p, prop)
    assert int(how) == lm.How.IDENTIFIED_FINE
    np.testing.assert_array_equal(m_fine.A, 2.0 * A_TRUE)
    _, r = s.update((rejected, st_next[1]), prop, outcome(), ms.no_objection())
    assert bool(r.trusted) and bool(r.fine) and not bool(r.handover)


def test_the_model_for_a_reduced_problem_carries_its_basis():
    r = 1
    V = jnp.broadcast_to(jnp.array([[1.0], [0.0]]), (T + 1, nx, r))
    lin = lambda X, U, K, key: (jnp.ones((T, r, r)), jnp.ones((T, r, nu)), V)  # noqa: E731
    p = make_problem()._replace(linearize=lin, model_rank=r)
    m0 = lm.init_model(p, ms.every_iteration(), *nominal(), jax.random.key(0), 3).model
    assert m0.A.shape == (T, r, r) and m0.V.shape == (T + 1, nx, r)
    m, _ = make(p, ms.Proposal(TRUE, FALSE, FALSE), m0)
    np.testing.assert_array_equal(m.V, V)


@pytest.mark.slow  # over 5 s: the fast tier's budget
def test_a_strategy_of_ones_own_plugs_in_through_the_problem():
    """A strategy that identifies only every other iteration (its own state: a counter), on
    a linear system: the loop identifies where it says, and the minimum is the same."""

    def every_other() -> ms.ModelStrategy:
        def propose(n, p):
            return p._replace(identify=(n % 2) == 0)

        def update(n, p, o, r):
            return n + 1, r

        return ms.ModelStrategy(lambda: jnp.asarray(0), propose, update)

    A = jnp.array([[1.0, 0.1], [0.0, 1.0]])
    B = jnp.array([[0.0], [0.1]])
    step = lambda x, u: A @ x + B @ u  # noqa: E731
    lin = lambda X, U, K, key: (jnp.broadcast_to(A, (T, nx, nx)), jnp.broadcast_to(B, (T, nx, nu)))  # noqa: E731
    cost = Cost(lambda x, u: jnp.sum(x**2) + jnp.sum(u**2), lambda x: 10.0 * jnp.sum(x**2))
    lim = jnp.full(nu, 100.0)
    base = Problem(step, lin, cost, jnp.array([1.0, 0.0]), -lim, lim)
    params = ILQRParams(max_iter=6, rel_tol=0.0, k_tol=0.0)
    U0 = jnp.zeros((T, nu))
    own = ilqr_result(
        ilqr_advance(
            base._replace(strategy=every_other()),
            ilqr_init(base._replace(strategy=every_other()), U0, params, jax.random.key(0)),
            params,
        )
    )
    default = ilqr_result(ilqr_advance(base, ilqr_init(base, U0, params, jax.random.key(0)), params))
    n = int(own.iterations)
    np.testing.assert_array_equal(np.asarray(own.identified)[:n], [1 - i % 2 for i in range(n)])
    accepted = np.asarray(default.alpha_history)[: int(default.iterations)] > 0
    want = np.r_[True, accepted[:-1]]  # the default identifies where the nominal moved
    np.testing.assert_array_equal(np.asarray(default.identified)[: int(default.iterations)] == 1, want)
    np.testing.assert_allclose(float(own.cost), float(default.cost), rtol=1e-9)


def test_the_first_models_zero_expansion_has_the_cost_derivatives_shapes_and_dtypes():
    """Built without tracing the cost's second derivatives, it is what tracing them gives:
    a free joint's quaternion error, float32 and mixed precision, point goals' own ones."""
    from mjx_surrogate.control.riccati import cost_derivatives, zero_cost_derivatives
    from mjx_surrogate.tasks import make_task, task_cost

    goal = np.r_[0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    quat = make_task(np.zeros(9), goal, np.eye(9), np.eye(9), np.eye(2), 3, quats=(2,))
    points = lambda x: jnp.stack([x[:3], 2 * x[:3]])  # noqa: E731
    goals = make_task(
        np.zeros(9), goal, np.eye(9), np.eye(9), np.eye(2), 3, points=points, targets=np.ones((2, 3))
    )
    for cost in (task_cost(quat), task_cost(goals)):
        for x_dtype, u_dtype in (
            (jnp.float64, jnp.float64),
            (jnp.float32, jnp.float32),
            (jnp.float64, jnp.float32),
        ):
            X, U = jnp.zeros((4, 9), x_dtype), jnp.zeros((3, 2), u_dtype)
            if cost.derivatives is not None and x_dtype != u_dtype:
                continue  # the Gauss-Newton derivatives take one precision
            want = jax.eval_shape(lambda X, U: cost_derivatives(cost, X, U), X, U)
            got = zero_cost_derivatives(cost, X, U)
            assert [(a.shape, a.dtype) for a in got] == [(w.shape, w.dtype) for w in want], (x_dtype, u_dtype)
            assert all(not np.any(np.asarray(a)) for a in got)
