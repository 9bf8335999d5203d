"""The t-test on the LTV regression against an independent float64 NumPy OLS: standard
errors from the residuals, the zero pattern, and the case it exists for (a row that is
not linear at the perturbation scale leaking into the control columns)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mjx_surrogate.identification import sysid
from mjx_surrogate.identification.sysid_significance import drop_insignificant, sum_of_squares

rng = np.random.default_rng(5)
A_TRUE = np.array([[1.0, 0.1, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
B_TRUE = np.array([[0.0], [0.1], [0.0]])  # row 2 (the "object") no control reaches


def jumpy_step(x, u):
    """Rows 0-1: linear (a driven double integrator); row 2: an object that no control
    reaches, whose next state jumps with the sign of its own coordinate (an impact)."""
    lin = jnp.asarray(A_TRUE) @ x + jnp.asarray(B_TRUE) @ u
    return lin.at[2].add(50.0 * jnp.sign(x[2]) * jnp.abs(x[2]) ** 0.5)


def curved_step(x, u):
    """jumpy_step with smooth curvature in the driven rows, so that their residuals (and
    t values) are well above round-off."""
    return jumpy_step(x, u).at[:2].add(0.3 * jnp.sin(x[:2]) * x[2] + 0.2 * u[0] ** 3)


def curved_step_numpy(x, u):
    """curved_step in float64 NumPy: the reference's own black box."""
    nxt = A_TRUE @ x + B_TRUE @ u
    nxt[2] += 50.0 * np.sign(x[2]) * np.abs(x[2]) ** 0.5
    nxt[:2] += 0.3 * np.sin(x[:2]) * x[2] + 0.2 * u[0] ** 3
    return nxt


def numpy_t_values(Z, Y):
    """Float64 OLS: coefficients W [nx, m] and |t| = |w| / se per coefficient."""
    n, m = Z.shape
    W, *_ = np.linalg.lstsq(Z, Y, rcond=None)
    rss = ((Y - Z @ W) ** 2).sum(0)  # [nx]
    se = np.sqrt(np.outer(rss / (n - m), np.diag(np.linalg.inv(Z.T @ Z))))  # [nx, m]
    return W.T, np.abs(W.T) / se


@pytest.mark.slow
@pytest.mark.parametrize("scheme", ["central_difference", "forward_difference"])
def test_zero_pattern_matches_numpy_ols_t_values(scheme):
    """Entries kept are the plain least-squares fit to round-off; an entry is zero exactly
    where NumPy's |t| is at most 3 (and the pattern differs from the untested fit)."""
    T, n = 3, 12
    X = jnp.asarray(rng.standard_normal((T + 1, 3)) * 0.3)
    U = jnp.asarray(rng.standard_normal((T, 1)))
    p0 = sysid.SysIdParams(1e-2, 1e-2, scheme=scheme, n_samples=n)
    key = jax.random.key(2)
    fit = sysid.central_difference if scheme == "central_difference" else sysid.forward_difference
    A0, B0 = fit(curved_step, X, U, key, p0)
    A3, B3 = fit(curved_step, X, U, key, p0.replace(significance=3.0))
    dx, du = (np.asarray(a) for a in sysid._one_step_perturbations(key, T, 3, 1, p0, jnp.float64))
    dropped = 0
    for t in range(T):
        Z = np.concatenate([dx[:, t], du[:, t]], axis=-1)
        x, u = np.asarray(X[t]), np.asarray(U[t])
        f = curved_step_numpy
        if scheme == "central_difference":
            Y = np.stack([0.5 * (f(x + a, u + b) - f(x - a, u - b)) for a, b in zip(dx[:, t], du[:, t])])
        else:
            Y = np.stack([f(x + a, u + b) - f(x, u) for a, b in zip(dx[:, t], du[:, t])])
        W, tv = numpy_t_values(Z, Y)
        np.testing.assert_allclose(np.concatenate([A0[t], B0[t]], 1), W, rtol=1e-8, atol=1e-12)
        kept = np.concatenate([A3[t], B3[t]], 1)
        np.testing.assert_array_equal(kept != 0, tv > 3.0)
        np.testing.assert_allclose(kept, np.where(tv > 3.0, W, 0.0), rtol=1e-8, atol=1e-12)
        dropped += int(((tv <= 3.0) & (W != 0)).sum())
    assert dropped > 0  # the test has work to do here


@pytest.mark.slow
def test_a_jumping_row_no_longer_leaks_into_the_control_column():
    """The object's row fitted across its jump gets a control coefficient far from its
    true 0; the t-test removes it and keeps the driven rows' exact coefficients."""
    T, n = 6, 40
    X = jnp.asarray(np.c_[rng.standard_normal((T + 1, 2)), np.full(T + 1, 1e-4)])  # object at its jump
    U = jnp.asarray(rng.standard_normal((T, 1)))
    p = sysid.SysIdParams(1e-3, 1e-3, n_samples=n)
    _, B0 = sysid.central_difference(jumpy_step, X, U, jax.random.key(0), p)
    A3, B3 = sysid.central_difference(jumpy_step, X, U, jax.random.key(0), p.replace(significance=3.0))
    assert float(jnp.abs(B0[:, 2]).max()) > 0.1  # the leak without the test
    assert float(jnp.abs(B3[:, 2]).max()) < 0.05 * float(jnp.abs(B0[:, 2]).max())
    np.testing.assert_allclose(A3[:, :2], np.broadcast_to(A_TRUE[:2], (T, 2, 3)), atol=1e-9)
    np.testing.assert_allclose(B3[:, :2], np.broadcast_to(B_TRUE[:2], (T, 2, 1)), atol=1e-9)


def test_without_spare_samples_nothing_is_dropped():
    """n = m leaves no residual degrees of freedom: every coefficient is kept."""
    Z = jnp.asarray(rng.standard_normal((2, 4, 4)))
    Y = jnp.asarray(rng.standard_normal((2, 4, 3)))
    G, F = sysid.normal_equations(Z, Y, None)
    A, B = sysid.solve_normal_equations(G, F, 3)
    A2, B2 = drop_insignificant(G, F, sum_of_squares(Y, None), A, B, 4, 3.0)
    np.testing.assert_array_equal(A2, A)
    np.testing.assert_array_equal(B2, B)


def test_padding_weights_change_nothing():
    """Samples of weight 0 (the padding of a sharded batch) count in no statistic."""
    Z = rng.standard_normal((2, 10, 4))
    Y = rng.standard_normal((2, 10, 3))
    w = jnp.asarray(np.r_[np.ones(7), np.zeros(3)])
    Zp, Yp = Z.copy(), Y.copy()
    Yp[:, 7:] = np.nan  # padding may hold anything
    S_pad = sum_of_squares(jnp.asarray(Yp), w)
    np.testing.assert_allclose(S_pad, sum_of_squares(jnp.asarray(Y[:, :7]), None), rtol=1e-12)
    G, F = sysid.normal_equations(jnp.asarray(Zp), jnp.asarray(Yp), w)
    A, B = sysid.solve_normal_equations(G, F, 3)
    A2, B2 = drop_insignificant(G, F, S_pad, A, B, 7, 2.0)
    for t in range(2):
        W, tv = numpy_t_values(Z[t, :7], Y[t, :7])
        np.testing.assert_array_equal(np.concatenate([A2[t], B2[t]], 1) != 0, tv > 2.0)
