"""The local model's strategies (``mjx_surrogate.control.local_model``): when the loop's model is
identified, carried over by a secant update or kept; coarse models hand over to fine ones;
minima are declared on trusted models only. The solver's state holds none of this."""

import jax
import jax.numpy as jnp
import numpy as np

from mjx_surrogate.control import local_model as lm
from mjx_surrogate.control.ilqr import ILQRParams, ILQRState, Problem
from mjx_surrogate.cost import Cost

T, nx, nu = 4, 2, 1
A_TRUE = jnp.broadcast_to(jnp.array([[1.0, 0.1], [0.0, 1.0]]), (T, nx, nx))
B_TRUE = jnp.broadcast_to(jnp.array([[0.0], [0.1]]), (T, nx, nu))


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


def state(problem, **reuse):
    m = lm.init_model(problem, *nominal())
    return m._replace(reuse=m.reuse._replace(**reuse))


def model(problem, m, X, U):
    return lm.model_for(problem, m, X, U, jnp.zeros((T, nu, nx)), jax.random.key(0), ())


def test_the_solver_state_holds_no_model_bookkeeping():
    bookkeeping = {"fresh", "stale", "fine", "fine_model", "reuse_ok", "reused", "X_model", "U_model"}
    assert not bookkeeping & set(ILQRState._fields)
    assert "model" in ILQRState._fields


def test_the_first_nominal_is_identified_and_a_minimum_may_be_declared_on_it():
    p = make_problem()
    m, how = model(p, lm.init_model(p, *nominal()), *nominal())
    assert int(how) == 1
    np.testing.assert_array_equal(m.A, A_TRUE)
    assert bool(lm.trusted(m))


def test_a_step_that_passed_the_reuse_test_carries_the_model_over_by_a_secant_update():
    p = make_problem()
    m0 = state(p, fresh=jnp.array(True), ok=jnp.array(True))
    m0 = m0._replace(A=A_TRUE, B=B_TRUE)
    X1, U1 = nominal(0.5)
    m, how = model(p, m0, X1, U1)
    assert int(how) == 0  # not identified
    A_ref, B_ref = lm.secant_update(A_TRUE, B_TRUE, X1 - m0.X, U1 - m0.U)
    np.testing.assert_allclose(m.A, A_ref, rtol=0, atol=0)
    np.testing.assert_allclose(m.B, B_ref, rtol=0, atol=0)
    assert bool(m.reuse.stale) and int(m.reuse.count) == 1
    assert not bool(lm.trusted(m))  # no minimum on a carried-over model
    np.testing.assert_array_equal(m.X, X1)  # the model now belongs to the new nominal


def test_a_step_rejected_on_a_carried_model_is_retried_on_an_identified_one():
    p = make_problem()
    m0 = state(p, fresh=jnp.array(False), stale=jnp.array(True), count=jnp.asarray(2))
    m, how = model(p, m0, *nominal())
    assert int(how) == 1 and not bool(m.reuse.stale) and int(m.reuse.count) == 0


def test_a_rejected_step_on_an_identified_model_keeps_it():
    p = make_problem()
    m0 = state(p, fresh=jnp.array(False))._replace(A=3.0 * A_TRUE)
    m, how = model(p, m0, *nominal())
    assert int(how) == 0
    np.testing.assert_array_equal(m.A, 3.0 * A_TRUE)


def test_the_reuse_test_and_its_limit():
    p = make_problem()
    params = ILQRParams(reuse_tol=0.2, reuse_max=2)
    m = state(p, count=jnp.asarray(1))

    def after(ratio, count=1, accepted=True, at_minimum=False):
        o = lm.StepOutcome(
            jnp.array(accepted), jnp.asarray(ratio), jnp.array(at_minimum), jnp.array(False), jnp.array(False)
        )
        return lm.after_step(params, m._replace(reuse=m.reuse._replace(count=jnp.asarray(count))), o)[0].reuse

    assert bool(after(1.1).ok) and bool(after(1.1).fresh)
    assert not bool(after(1.3).ok)  # the model's promise missed by more than reuse_tol
    assert not bool(after(1.1, count=2).ok)  # reuse_max carried-over models in a row
    assert not bool(after(1.1, at_minimum=True).ok)
    r = after(1.0, accepted=False)
    assert not bool(r.ok) and not bool(r.fresh)


def test_a_coarse_model_hands_over_to_the_fine_one_and_only_that_is_trusted():
    p = make_problem(with_fine=True)
    m, how = model(p, lm.init_model(p, *nominal()), *nominal())
    assert int(how) == 1 and not bool(lm.is_fine(m)) and not bool(lm.trusted(m))
    np.testing.assert_array_equal(m.A, A_TRUE)  # the coarse model
    o = lm.StepOutcome(
        jnp.array(True), jnp.asarray(1.0), jnp.array(False), jnp.array(False), jnp.array(False)
    )
    m_go_on, handover = lm.after_step(ILQRParams(), m, o)
    assert not bool(handover) and not bool(m_go_on.refine.fine)
    for reason in range(3):  # a minimum, a small gain or a stall on the coarse model
        flags = [jnp.array(i == reason) for i in range(3)]
        o = lm.StepOutcome(jnp.array(True), jnp.asarray(1.0), *flags)
        m_next, handover = lm.after_step(ILQRParams(), m, o)
        assert bool(handover) and bool(m_next.refine.fine)
    m_fine, how = model(p, m_next._replace(reuse=m_next.reuse._replace(fresh=jnp.array(False))), *nominal())
    assert int(how) == 2 and bool(lm.trusted(m_fine))  # identified again, by the fine model
    np.testing.assert_array_equal(m_fine.A, 2.0 * A_TRUE)


def test_the_model_for_a_reduced_problem_carries_its_basis():
    r = 1
    V = jnp.broadcast_to(jnp.array([[1.0], [0.0]]), (T + 1, nx, r))
    lin = lambda X, U, K, key: (jnp.ones((T, r, r)), jnp.ones((T, r, nu)), V)  # noqa: E731
    p = make_problem()._replace(linearize=lin, model_rank=r)
    m0 = lm.init_model(p, *nominal())
    assert m0.A.shape == (T, r, r) and m0.V.shape == (T + 1, nx, r)
    m, _ = model(p, m0, *nominal())
    np.testing.assert_array_equal(m.V, V)


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
