"""iLQR against closed-form references: discrete Riccati (LQR), a box-constrained
convex QP solved by SciPy, and divergence handling."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.optimize import minimize

from mjx_surrogate.control.ilqr import Cost, ILQRParams, StopReason, ilqr

A = np.array([[1.0, 0.1], [0.0, 1.0]])
B = np.array([[0.005], [0.1]])
Q = np.diag([1.0, 0.1])
QF = np.diag([10.0, 1.0])
R = np.array([[0.01]])
X0 = np.array([1.0, -0.5])
T = 25


def linear_problem(A=A, B=B):
    step = lambda x, u: jnp.asarray(A) @ x + jnp.asarray(B) @ u  # noqa: E731
    lin = lambda X, U, K, key: (
        jnp.broadcast_to(jnp.asarray(A), (U.shape[0],) + A.shape),  # noqa
        jnp.broadcast_to(jnp.asarray(B), (U.shape[0],) + B.shape),
    )
    cost = Cost(lambda x, u: 0.5 * x @ Q @ x + 0.5 * u @ R @ u, lambda x: 0.5 * x @ QF @ x)
    return step, lin, cost


def riccati_lqr():
    """Independent NumPy reference: finite-horizon discrete LQR, u_t = -L_t x_t."""
    P = QF
    L = []
    for _ in range(T):
        Lt = np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)
        P = Q + A.T @ P @ (A - B @ Lt)
        L.append(Lt)
    L = L[::-1]
    x, U, X = X0, [], [X0]
    for t in range(T):
        u = -L[t] @ x
        x = A @ x + B @ u
        U.append(u)
        X.append(x)
    return np.array(L), np.array(U), np.array(X)


def run(step, lin, cost, U0, lo=-np.inf, hi=np.inf, **kw):
    """iLQR from X0 under jit with the given model; kw: ILQRParams fields."""
    f = lambda U0: ilqr(
        step,
        lin,
        cost,
        jnp.asarray(X0),
        U0,
        jnp.full(1, lo),
        jnp.full(1, hi),
        ILQRParams(**kw),
        jax.random.key(0),
    )
    return jax.jit(f)(U0)


def solve(U0, lo=-np.inf, hi=np.inf, **kw):
    return run(*linear_problem(), U0, lo, hi, **kw)


def test_matches_discrete_riccati():
    L, U_ref, X_ref = riccati_lqr()
    res = solve(jnp.zeros((T, 1)), rel_tol=1e-12)
    assert bool(res.converged)
    np.testing.assert_allclose(res.U, U_ref, atol=1e-9)
    np.testing.assert_allclose(res.X, X_ref, atol=1e-9)
    np.testing.assert_allclose(res.K, -L, atol=1e-6)  # feedback gains of the final nominal
    assert res.U.dtype == jnp.float64
    # one Newton step solves an LQ problem exactly: the first step takes alpha = 1
    assert float(res.alpha_history[0]) == 1.0
    # limits that never bind take the box-QP path and give the same answer
    wide = solve(jnp.zeros((T, 1)), -1e9, 1e9, rel_tol=1e-12)
    np.testing.assert_allclose(wide.U, res.U, atol=1e-10)
    np.testing.assert_allclose(wide.K, res.K, atol=1e-8)


def test_box_limits_match_convex_qp_reference():
    lo, hi = -0.5, 0.5
    res = solve(jnp.zeros((T, 1)), lo, hi, rel_tol=1e-12, max_iter=200)

    def J(u):
        x, c = X0, 0.0
        for t in range(T):
            c += 0.5 * x @ Q @ x + 0.5 * R[0, 0] * u[t] ** 2
            x = A @ x + B[:, 0] * u[t]
        return c + 0.5 * x @ QF @ x

    ref = minimize(
        J,
        np.zeros(T),
        method="L-BFGS-B",
        bounds=[(lo, hi)] * T,
        options={"ftol": 1e-15, "gtol": 1e-12, "maxiter": 10000},
    )
    U = np.asarray(res.U)[:, 0]
    assert U.min() >= lo - 1e-12 and U.max() <= hi + 1e-12
    assert np.sum(np.isclose(np.abs(U), hi)) > 0  # the limits are active
    assert float(res.cost) == pytest.approx(ref.fun, rel=1e-6)
    np.testing.assert_allclose(U, ref.x, atol=1e-4)
    unconstrained = solve(jnp.zeros((T, 1)), rel_tol=1e-12)
    assert float(res.cost) > float(unconstrained.cost)


def test_returned_gains_are_the_unregularised_lqr_gains_after_a_regularised_last_step():
    """A solve whose iterations ran at mu 1e6 returns the discrete LQR gains: the result's K
    is TVLQR of the final nominal with no regularisation (``ilqr.final_gains``), not the
    last iteration's, which mu B'B pushes towards -(B'B)^-1 B'A."""
    L, _, _ = riccati_lqr()
    res = solve(jnp.zeros((T, 1)), mu_init=1e6, mu_min=1e6, max_iter=2)
    assert int(res.iterations) == 2 and float(res.mu) >= 1e6
    np.testing.assert_allclose(res.K, -L, atol=1e-6)


@pytest.mark.slow
def test_tvlqr_gains_equal_the_backward_pass_at_a_box_constrained_optimum():
    """At an optimum with active limits, :func:`riccati.tvlqr_gains` (k taken as 0, the
    clamped set read off U and Q_u) gives the backward pass's K, zero rows included."""
    from mjx_surrogate.control.riccati import backward_pass, cost_derivatives, tvlqr_gains

    lo, hi = jnp.full(1, -0.5), jnp.full(1, 0.5)
    res = solve(jnp.zeros((T, 1)), -0.5, 0.5, rel_tol=1e-12, max_iter=200)
    step, lin, cost = linear_problem()
    Aa, Ba = lin(res.X, res.U, None, None)
    derivs = cost_derivatives(cost, res.X, res.U)
    _, K_bp, _, ok_bp, _ = backward_pass(Aa, Ba, *derivs, res.U, lo, hi, 0.0)
    K_tv, ok_tv = tvlqr_gains(Aa, Ba, *derivs, res.U, lo, hi, 0.0)
    assert bool(ok_bp) and bool(ok_tv)
    clamped = np.isclose(np.abs(np.asarray(res.U)[:, 0]), 0.5)
    assert clamped.any() and np.all(np.asarray(K_tv)[clamped] == 0.0)
    np.testing.assert_allclose(K_tv, K_bp, atol=1e-9)


@pytest.mark.parametrize("mu", [0.0, 1.0, 1e4, 1e8])
def test_regularised_step_keeps_an_exact_value_model(mu):
    """On a linear system with a quadratic cost, the full step (alpha 1) of the regularised
    policy changes J by exactly dV1 + dV2 for every mu, and Q~_uu stays positive definite:
    V and dV are the plain (unregularised) value of that policy. A small B (as on swimmer6)
    made the regularised value update go indefinite at large mu."""
    from mjx_surrogate.control.ilqr import closed_loop, trajectory_cost
    from mjx_surrogate.control.riccati import backward_pass, cost_derivatives

    Bs = 1e-2 * B
    step, lin, cost = linear_problem(B=Bs)
    U = 0.3 * jax.random.normal(jax.random.key(3), (T, 1))
    inf = jnp.full(1, jnp.inf)
    X, _ = closed_loop(
        step,
        jnp.asarray(X0),
        jnp.zeros((T + 1, 2)),
        U,
        jnp.zeros((T, 1)),
        jnp.zeros((T, 1, 2)),
        0.0,
        -inf,
        inf,
    )
    Aa, Ba = lin(X, U, None, None)
    k, K, dV, ok, _ = backward_pass(Aa, Ba, *cost_derivatives(cost, X, U), U, -inf, inf, mu)
    assert bool(ok)
    Xn, Un = closed_loop(step, jnp.asarray(X0), X, U, k, K, 1.0, -inf, inf)
    dJ = float(trajectory_cost(cost, Xn, Un) - trajectory_cost(cost, X, U))
    assert dJ < 0
    assert dJ == pytest.approx(float(dV[0] + dV[1]), rel=1e-9)


def test_blown_up_trials_rejected_and_nonfinite_start_reported():
    # Unstable system: the initial controls blow the state up -> reported, no crash.
    step, lin, cost = linear_problem(A=np.array([[1.3, 0.1], [0.0, 1.3]]))
    f = lambda U0: run(step, lin, cost, U0)  # noqa: E731
    res = f(jnp.full((T, 1), 1e300))
    assert StopReason(int(res.stop_reason)) == StopReason.NOT_FINITE
    assert StopReason(int(res.stop_reason)).verdict == "diverged"
    assert not bool(res.converged) and int(res.iterations) == 0
    # From a finite start the same unstable system is solved, never accepting an inf trial.
    res = f(jnp.zeros((T, 1)))
    h = np.asarray(res.cost_history)[: int(res.iterations) + 1]
    assert np.all(np.isfinite(h)) and np.all(np.diff(h) <= 0)


def bilinear_problem():
    """x = [p, v], v' = v + 0.1 u p: at p = 0 the controls act on nothing, so every local
    model says they do not change the cost (a goal at p = 1 all the same)."""
    step = lambda x, u: jnp.stack([x[0] + 0.1 * x[1], x[1] + 0.1 * u[0] * x[0]])  # noqa: E731
    jac = jax.vmap(jax.jacfwd(step, argnums=(0, 1)))
    lin = lambda X, U, K, key: jac(X[:-1], U)  # noqa: E731
    goal = jnp.array([1.0, 0.0])
    cost = Cost(lambda x, u: 0.005 * u @ u, lambda x: 50.0 * (x - goal) @ (x - goal))
    return step, lin, cost


def solve_from(problem, x0, U0, **kw):
    step, lin, cost = problem
    f = lambda x0, U0: ilqr(
        step, lin, cost, x0, U0, jnp.full(1, -10.0), jnp.full(1, 10.0), ILQRParams(**kw), jax.random.key(0)
    )
    return jax.jit(f)(jnp.asarray(x0, float), U0)


def test_a_start_where_the_controls_act_on_nothing_is_stationary_not_converged():
    res = solve_from(bilinear_problem(), [0.0, 0.0], jnp.zeros((T, 1)))
    reason = StopReason(int(res.stop_reason))
    assert reason == StopReason.STATIONARY and reason.verdict == "stationary", reason.description
    assert not bool(res.converged) and int(res.iterations) == 1
    assert float(res.cost) == float(res.cost_history[0]) == 50.0  # no decrease at all
    # The control: the same system from a start where the controls act is solved and
    # converges (a minimum rule after a decrease), so the rule can tell the two apart.
    moved = solve_from(bilinear_problem(), [0.5, 0.0], jnp.zeros((T, 1)))
    assert bool(moved.converged), StopReason(int(moved.stop_reason)).description
    assert float(moved.cost) < 0.01 * float(moved.cost_history[0])


def test_a_model_that_turns_non_finite_stops_diverged_keeping_the_last_finite_iterate():
    # The exact LQ model, until the nominal leaves |u| < 1e-3 (the first step, to the LQR
    # optimum): then NaN, as a black box that fails mid-solve gives.
    step, lin, cost = linear_problem()
    nan_later = lambda X, U, K, key: tuple(  # noqa: E731
        M * jnp.where(jnp.max(jnp.abs(U)) > 1e-3, jnp.nan, 1.0) for M in lin(X, U, K, key)
    )
    res = run(step, nan_later, cost, jnp.zeros((T, 1)), rel_tol=1e-12, mu_init=0.0)
    reason = StopReason(int(res.stop_reason))
    assert reason == StopReason.MODEL_NOT_FINITE and reason.verdict == "diverged", reason.description
    assert int(res.iterations) == 2 and not bool(res.converged)  # stopped at once, not after mu_max
    _, U_ref, X_ref = riccati_lqr()
    np.testing.assert_allclose(res.U, U_ref, atol=1e-9)  # iteration 1's iterate, finite, kept
    np.testing.assert_allclose(res.X, X_ref, atol=1e-9)
    assert np.isfinite(float(res.cost)) and float(res.cost) == float(res.cost_history[1])


def test_absurd_weights_reported_not_nan():
    step, lin, _ = linear_problem()
    cost = Cost(lambda x, u: 0.5 * 1e300 * x @ x + 0.5 * u @ u, lambda x: 1e300 * (1e300 * x @ x))
    res = run(step, lin, cost, jnp.zeros((T, 1)), max_iter=20)
    assert not bool(res.converged)
    assert StopReason(int(res.stop_reason)) == StopReason.NOT_FINITE
    assert StopReason(int(res.stop_reason)).verdict == "diverged"
    np.testing.assert_array_equal(res.U, 0.0)  # what it had is kept, finite


def test_spd_solve_matches_numpy_and_detects_indefinite():
    from mjx_surrogate.linalg import spd_solve

    rng = np.random.default_rng(0)
    M = rng.standard_normal((6, 6))
    A = M @ M.T + 0.1 * np.eye(6)
    B = rng.standard_normal((6, 3))
    X, ok = spd_solve(jnp.asarray(A), jnp.asarray(B))
    assert bool(ok)
    np.testing.assert_allclose(X, np.linalg.solve(A, B), rtol=1e-9, atol=1e-12)
    x, ok = spd_solve(jnp.asarray(A), jnp.asarray(B[:, 0]))
    np.testing.assert_allclose(x, np.linalg.solve(A, B[:, 0]), rtol=1e-9, atol=1e-12)
    _, ok = spd_solve(jnp.asarray(np.diag([1.0, -1.0, 2.0])), jnp.ones(3))
    assert not bool(ok)


@pytest.mark.parametrize("threads", [1, 3])
def test_native_one_call_line_search_equals_the_per_step_rollouts(threads):
    """System.closed_loop (one host call for all step sizes, on one thread or spread over
    three) = closed_loop over step, diverged trials included."""
    import jax
    import jax.numpy as jnp

    from mjx_surrogate.control.ilqr import closed_loop
    from mjx_surrogate.systems import make_system

    sys_ = make_system("cartpole", backend="native", native_threads=threads)
    T, nu, nx = 12, sys_.nu, sys_.nx
    key = jax.random.key(0)
    k1, k2, k3 = jax.random.split(key, 3)
    x0 = jnp.array([0.0, 3.0, 0.0, 0.0])
    Ub = 0.5 * jax.random.normal(k1, (T, nu))
    Xb = sys_.rollout(x0[None], Ub[None])[0] + 0.01
    k = jax.random.normal(k2, (T, nu)).at[5].set(-1e12)  # beyond mjMAXVAL at alpha >= 1/8
    K = 0.3 * jax.random.normal(k3, (T, nu, nx))
    alphas = 0.5 ** jnp.arange(5.0) * jnp.array([1.0, 1.0, 1.0, 1.0, 1e-12])
    lo, hi = jnp.full(nu, -jnp.inf), jnp.full(nu, 0.9)
    X1, U1 = jax.jit(sys_.closed_loop)(x0, Xb, Ub, k, K, alphas, lo, hi)
    ref = jax.vmap(lambda a: closed_loop(sys_.step, x0, Xb, Ub, k, K, a, lo, hi))
    X2, U2 = jax.jit(ref)(alphas)
    assert float(jnp.nanmax(U1)) <= 0.9
    assert bool(jnp.isnan(X1[:4, 6:]).all()) and bool(jnp.isfinite(X1[:4, :6]).all())
    assert bool(jnp.isfinite(X1[4]).all())  # the smallest step stays below mjMAXVAL
    np.testing.assert_allclose(U1[:, :6], U2[:, :6], atol=1e-12)
    np.testing.assert_allclose(X1, X2, atol=1e-12)


def test_native_initial_rollout_is_one_host_call_equal_to_the_per_step_scan():
    """ilqr_init rolls U0 out through the backend's batched line-search call (one host
    call) rather than a scan of T one-step calls, to the same states in float64, clipped
    controls included."""
    import jax
    import jax.numpy as jnp

    from mjx_surrogate.control.d2c import problem
    from mjx_surrogate.control.ilqr import ILQRParams, closed_loop, ilqr_init
    from mjx_surrogate.identification.sysid import SysIdParams
    from mjx_surrogate.systems import backend_native, make_system
    from mjx_surrogate.tasks import make_task

    # float64 throughout (tests/conftest.py)
    sys_ = make_system("cartpole", backend="native", native_threads=1)
    T = 20
    task = make_task([0.0, 3.0, 0.0, 0.0], np.zeros(4), np.eye(4), np.eye(4), np.eye(1), T, [-1.0], [1.0])
    prob = problem(sys_, task, SysIdParams(), "d2c")
    U0 = 0.8 * jax.random.normal(jax.random.key(3), (T, sys_.nu), jnp.float64)  # some beyond +-1
    calls, Sim = [], backend_native.NativeSimulator
    orig = Sim.__call__, Sim.step
    Sim.__call__ = lambda self, *a: calls.append("rollout") or orig[0](self, *a)
    Sim.step = lambda self, *a: calls.append("step") or orig[1](self, *a)
    try:
        X0 = jax.jit(lambda U: ilqr_init(prob, U, ILQRParams(max_iter=3), jax.random.key(0)).solver.X)(U0)
    finally:
        Sim.__call__, Sim.step = orig
    assert calls == []  # no one-step callback: the batched trial rollout did it
    Uc = jnp.clip(U0, task.u_min, task.u_max)
    zeros = jnp.zeros((T + 1, sys_.nx)), jnp.zeros((T, sys_.nu, sys_.nx))
    no_k = jnp.zeros_like(Uc)
    ref, _ = closed_loop(sys_.step, task.x0, zeros[0], Uc, no_k, zeros[1], 0.0, -jnp.inf, jnp.inf)
    np.testing.assert_array_equal(np.asarray(X0), np.asarray(ref))


def test_a_wrong_model_stalls_instead_of_converging_on_regularised_steps():
    # The model's B has the wrong sign: trials fail and mu grows until the regularised
    # step (k ~ 1/mu) and its promise are tiny. That is no minimum: the
    # verdict must be "stalled", not a small-step or noise-floor "converged".
    step, _, cost = linear_problem()
    _, wrong, _ = linear_problem(B=-B)
    res = run(step, wrong, cost, jnp.zeros((T, 1)), max_iter=100)
    assert int(res.iterations) > 1
    assert StopReason(int(res.stop_reason)) == StopReason.NO_DESCENT
    assert not bool(res.converged)


@pytest.mark.slow
def test_a_heavily_regularised_step_gaining_little_is_no_converged_cost_change():
    # mu_init 1e4 makes the first steps about 1e4 times shorter than Newton's: their small
    # gain says nothing about a minimum (once declared "converged" at 1.7x the optimum).
    opt = solve(jnp.zeros((T, 1)), max_iter=60, rel_tol=1e-9)
    res = solve(jnp.zeros((T, 1)), max_iter=60, rel_tol=1e-3, mu_init=1e4)
    assert bool(res.converged)
    assert float(res.cost) == pytest.approx(float(opt.cost), rel=1e-5)


@pytest.mark.slow
def test_short_accepted_steps_raise_mu_up_to_mu_max_without_stalling():
    zeros = jnp.zeros((T, 1))
    # A linear model: the full step is accepted; raise below alpha 1.5 treats it as short.
    assert float(solve(zeros, max_iter=1, mu_init=1e-3).mu) == pytest.approx(1e-3 / 4)
    assert float(solve(zeros, max_iter=1, mu_init=1e-3, mu_raise_alpha=1.5).mu) == pytest.approx(4e-3)
    # Raised by accepted steps, mu stops at mu_max: only rejections end a solve there.
    res = solve(zeros, max_iter=60, mu_init=1e-3, mu_max=1e-3, mu_raise_alpha=1.5)
    assert StopReason(int(res.stop_reason)) == StopReason.COST_CHANGE
    assert float(res.mu) == pytest.approx(1e-3)


def test_batched_feedback_rollouts_equal_the_vmapped_rollout():
    from mjx_surrogate.trajectory import feedback_rollout, feedback_rollouts

    rng = np.random.default_rng(0)
    T, nx, nu, n = 12, 3, 2, 4
    step = lambda x, u: jnp.sin(x) + 0.1 * jnp.concatenate([u, u[:1]]) * x  # noqa: E731
    X_bar, U_bar = jnp.asarray(rng.normal(size=(T + 1, nx))), jnp.asarray(rng.normal(size=(T, nu)))
    K, V = jnp.asarray(rng.normal(size=(T, nu, nx))), jnp.asarray(rng.normal(size=(n, T, nu)))
    x0, lo, hi = X_bar[0] + 0.1, jnp.array([-0.5, -1.0]), jnp.array([0.5, jnp.inf])
    X, U = feedback_rollouts(step, x0, X_bar, U_bar, K, V, lo, hi)
    one = jax.vmap(feedback_rollout, in_axes=(None, None, None, None, None, 0, None, None))
    X1, U1 = one(step, x0, X_bar, U_bar, K, V, lo, hi)
    assert X.shape == (n, T + 1, nx) and U.shape == (n, T, nu)
    np.testing.assert_allclose(np.asarray(X), np.asarray(X1), rtol=0, atol=1e-13)
    np.testing.assert_allclose(np.asarray(U), np.asarray(U1), rtol=0, atol=1e-13)
    assert float(jnp.max(U[..., 0])) <= 0.5 and float(jnp.min(U[..., 1])) >= -1.0


def test_cost_derivatives_are_jax_grad_and_hessian_from_one_program():
    """The running and terminal expansions (one forward-over-reverse program each) equal
    ``jax.grad`` and ``jax.hessian`` of a non-quadratic cost, term by term."""
    from mjx_surrogate.control.riccati import cost_derivatives
    from mjx_surrogate.cost import Cost

    running = lambda x, u: jnp.sum(jnp.sin(x) * x[::-1]) + jnp.cos(x[0] * u[1]) + u @ u * x[1]  # noqa: E731
    terminal = lambda x: jnp.sum(jnp.exp(0.3 * x) * x**2)  # noqa: E731
    rng = np.random.default_rng(3)
    X, U = jnp.asarray(rng.normal(size=(5, 3))), jnp.asarray(rng.normal(size=(4, 2)))
    expansion = jax.jit(lambda X, U: cost_derivatives(Cost(running, terminal), X, U))(X, U)

    @jax.jit
    def reference(X, U):  # jitted: eager, each of its operations would compile on its own
        gx, gu = jax.vmap(jax.grad(running, argnums=(0, 1)))(X[:-1], U)
        (hxx, _), (hux, huu) = jax.vmap(jax.hessian(running, argnums=(0, 1)))(X[:-1], U)
        return gx, gu, hxx, huu, hux, jax.grad(terminal)(X[-1]), jax.hessian(terminal)(X[-1])

    for got, want in zip(expansion, reference(X, U)):
        assert got.shape == want.shape
        np.testing.assert_allclose(got, want, rtol=1e-13, atol=1e-13)
