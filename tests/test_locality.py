"""Locality measures against closed forms and a float64 Monte Carlo."""

import jax.numpy as jnp
import numpy as np

from mjx_surrogate.analysis import locality


def test_relative_spread_is_the_median_largest_deviation_over_the_excursion():
    T = 10
    X_star = np.stack([np.linspace(0.0, 2.0, T + 1), np.zeros(T + 1)], axis=1)  # excursion 2
    bump = np.zeros((T + 1, 2))
    bump[4, 1] = 1.0
    X = np.stack([X_star + d * bump for d in (0.2, 0.4, 0.6)] + [np.full_like(X_star, np.nan)])
    # largest deviations 0.2, 0.4, 0.6, inf: median 0.5, over the excursion 2
    assert float(locality.relative_spread(jnp.asarray(X), jnp.asarray(X_star))) == 0.25


def test_open_loop_gain_matches_the_geometric_sum_and_a_monte_carlo():
    T, a, b = 20, 1.1, 0.5
    A = jnp.full((T, 1, 1), a)
    B = jnp.full((T, 1, 1), b)
    closed = np.sqrt(b**2 * sum(a ** (2 * k) for k in range(T)) / T)
    np.testing.assert_allclose(float(locality.open_loop_gain(A, B)), closed, rtol=1e-12)
    # time-varying, several states and controls: E|x_T|^2 = trace P_T, checked by sampling
    rng = np.random.default_rng(0)
    nx, nu, T = 3, 2, 15
    A = 0.9 * np.eye(nx) + 0.2 * rng.standard_normal((T, nx, nx))
    B = rng.standard_normal((T, nx, nu))
    x = np.zeros((200_000, nx))
    for t in range(T):
        x = x @ A[t].T + rng.standard_normal((len(x), nu)) @ B[t].T
    mc = np.sqrt(np.mean(np.sum(x**2, axis=1)) / (T * nu))
    g = float(locality.open_loop_gain(jnp.asarray(A), jnp.asarray(B)))
    np.testing.assert_allclose(g, mc, rtol=0.01)
