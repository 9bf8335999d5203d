"""Model reuse in iLQR (``reuse_tol``, ``reuse_max``): the secant update against a NumPy
float64 reference, and solves that reuse reach the same optimum with fewer
identifications, never declaring a minimum on a carried-over model."""

import types

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mjx_surrogate.control.ilqr import Cost, ILQRParams, StopReason, ilqr
from mjx_surrogate.control.local_model import secant_update
from mjx_surrogate.identification import sysid

rng = np.random.default_rng(4)


def test_secant_update_matches_broyden_in_float64_numpy():
    T, nx, nu = 5, 3, 2
    A, B = rng.standard_normal((T, nx, nx)), rng.standard_normal((T, nx, nu))
    dX, dU = rng.standard_normal((T + 1, nx)), rng.standard_normal((T, nu))
    dU[2] = 0.0
    dX[2] = 0.0  # no step at t = 2: W_2 unchanged
    A1, B1 = secant_update(jnp.asarray(A), jnp.asarray(B), jnp.asarray(dX), jnp.asarray(dU))
    for t in range(T):
        W = np.hstack([A[t], B[t]])
        s = np.concatenate([dX[t], dU[t]])
        ref = W if t == 2 else W + np.outer(dX[t + 1] - W @ s, s) / (s @ s)
        np.testing.assert_allclose(np.hstack([A1[t], B1[t]]), ref, rtol=1e-12, atol=1e-12)
        if t != 2:  # the secant condition, and no change orthogonal to s
            np.testing.assert_allclose(ref @ s, dX[t + 1], atol=1e-12)
            q = rng.standard_normal(nx + nu)
            q -= (q @ s) / (s @ s) * s
            np.testing.assert_allclose(ref @ q, W @ q, atol=1e-12)


def pendulum(x, u):
    """A damped pendulum with an unmodelled cubic spring, dt 0.05: smooth and nonlinear."""
    th, om = x
    acc = -9.81 * jnp.sin(th) - 0.1 * om - 0.5 * th**3 + u[0]
    return jnp.stack([th + 0.05 * om, om + 0.05 * acc])


def solve(reuse_tol: float, reuse_max: int):
    p = sysid.SysIdParams(sigma_x=1e-5, sigma_u=1e-5, scheme="forward_difference", n_samples=3)
    p_orth = p.replace(design="orthogonal")
    lin = sysid.ltv_linearize(types.SimpleNamespace(step=pendulum), p_orth)
    goal = jnp.array([jnp.pi, 0.0])
    cost = Cost(
        lambda x, u: 0.01 * u @ u + 0.1 * (x - goal) @ (x - goal), lambda x: 50.0 * (x - goal) @ (x - goal)
    )
    params = ILQRParams(max_iter=200, rel_tol=1e-9, reuse_tol=reuse_tol, reuse_max=reuse_max)
    inf = jnp.full(1, jnp.inf)
    x0, U0 = jnp.zeros(2), jnp.zeros((40, 1))
    return jax.jit(lambda: ilqr(pendulum, lin, cost, x0, U0, -inf, inf, params, jax.random.key(0)))()


def identified_at_its_nominal(res) -> bool:
    """The last iteration's model was identified at that iteration's nominal: no step was
    accepted between the last identification and the final iteration."""
    it = int(res.iterations)
    ident = np.asarray(res.identified)[:it]
    last = np.nonzero(ident)[0][-1]
    return bool(np.all(np.asarray(res.alpha_history)[last : it - 1] == 0))


@pytest.mark.slow
@pytest.mark.parametrize("reuse_tol, reuse_max", [(0.3, 5), (1e9, 1000)])
def test_reuse_reaches_the_same_optimum_with_fewer_identifications(reuse_tol, reuse_max):
    ref = solve(0.0, 0)
    res = solve(reuse_tol, reuse_max)
    assert bool(ref.converged) and bool(res.converged), StopReason(int(res.stop_reason)).description
    n_ref, n = int(np.sum(ref.identified)), int(np.sum(res.identified))
    rejected = int(np.sum(np.asarray(ref.alpha_history)[: int(ref.iterations) - 1] == 0))
    assert n_ref == int(ref.iterations) - rejected  # without reuse: identified unless rejected
    assert n < n_ref
    np.testing.assert_allclose(float(res.cost), float(ref.cost), rtol=1e-6)
    assert identified_at_its_nominal(res)


def test_orthogonal_design_is_perfectly_conditioned():
    T, nx, nu = 4, 3, 2
    p = sysid.SysIdParams(sigma_x=0.1, sigma_u=0.01, n_samples=2 * (nx + nu), design="orthogonal")
    dx, du = sysid._one_step_perturbations(jax.random.key(0), T, nx, nu, p, jnp.float64)
    Z = np.concatenate([dx, du], axis=-1)  # [n, T, m]
    scale = np.array([0.1] * nx + [0.01] * nu)
    for half in (Z[: nx + nu], Z[nx + nu :]):  # each block of m rows: orthogonal, scaled columns
        G = np.einsum("nti,ntj->tij", half / scale, half / scale)
        np.testing.assert_allclose(G, np.broadcast_to(np.eye(nx + nu), G.shape), atol=1e-12)
