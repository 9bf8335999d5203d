"""iLQR on a surrogate (`surrogate_control.solve_on_model`): the linear-quadratic optimum
by least squares in NumPy as the reference; new coefficients do not recompile."""

import jax
import jax.numpy as jnp
import numpy as np

from mjx_surrogate.control.ilqr import ILQRParams
from mjx_surrogate.control.surrogate_control import solve_on_model
from mjx_surrogate.surrogates.library import LibrarySpec
from mjx_surrogate.surrogates.sindy import SindyModel
from mjx_surrogate.tasks import Task

T, NX, NU = 20, 2, 1


def _task() -> Task:
    inf = jnp.full(NU, jnp.inf)
    return Task(
        x0=jnp.array([1.0, -0.5]), x_goal=jnp.array([0.3, 0.0]), Q=jnp.diag(jnp.array([1.0, 0.2])),
        Q_f=50.0 * jnp.eye(NX), R=0.1 * jnp.eye(NU), u_min=-inf, u_max=inf, u_ref=jnp.full(NU, 0.2),
        targets=jnp.zeros((0, 3)), weights=jnp.zeros(0), final_weights=jnp.zeros(0), T=T,
    )  # fmt: skip


def _affine_model(A, B, c) -> SindyModel:
    """x' = A x + B u + c as a degree-1 library [1, x, u] with coefficients [c; A'; B']."""
    return SindyModel(jnp.asarray(np.vstack([c[None], A.T, B.T])), LibrarySpec(degree=1), False)


def _lq_optimum(A, B, c, task) -> np.ndarray:
    """The controls [T, nu] minimising the task's quadratic cost on x' = A x + B u + c: the
    states are affine in the stacked controls, so the optimum is one least-squares solve."""
    x0, g, ur = (np.asarray(a, float) for a in (task.x0, task.x_goal, task.u_ref))
    Qh, Qfh, Rh = (np.linalg.cholesky(np.asarray(M, float)).T for M in (task.Q, task.Q_f, task.R))
    Phi, Gam, off = [np.eye(NX)], [np.zeros((NX, T * NU))], [np.zeros(NX)]  # x_t = Phi x0 + Gam U + off
    for t in range(T):
        G = A @ Gam[-1]
        G[:, t * NU : (t + 1) * NU] += B
        Phi.append(A @ Phi[-1]), Gam.append(G), off.append(A @ off[-1] + c)
    rows, rhs = [], []
    for t in range(1, T + 1):  # x_0 does not depend on U
        W = Qfh if t == T else Qh
        rows.append(W @ Gam[t]), rhs.append(W @ (g - Phi[t] @ x0 - off[t]))
    for t in range(T):
        S = np.zeros((NU, T * NU))
        S[:, t * NU : (t + 1) * NU] = Rh
        rows.append(S), rhs.append(Rh @ ur)
    return np.linalg.lstsq(np.vstack(rows), np.concatenate(rhs), rcond=None)[0].reshape(T, NU)


def test_ilqr_on_an_affine_surrogate_reaches_the_least_squares_optimum():
    rng = np.random.default_rng(0)
    A = np.array([[1.0, 0.1], [-0.2, 0.95]]) + 0.02 * rng.normal(size=(NX, NX))
    B, c = np.array([[0.0], [0.1]]), np.array([0.01, -0.02])
    task = _task()
    res = solve_on_model(
        _affine_model(A, B, c), task, jnp.zeros((T, NU)), ILQRParams(max_iter=20, rel_tol=1e-12)
    )
    assert bool(res.converged)
    np.testing.assert_allclose(res.U, _lq_optimum(A, B, c, task), rtol=1e-7, atol=1e-9)


def test_new_coefficients_do_not_recompile():
    task, params = _task(), ILQRParams(max_iter=5)
    A, B = np.eye(NX), np.array([[0.0], [0.1]])
    solve_on_model(_affine_model(A, B, np.zeros(NX)), task, jnp.zeros((T, NU)), params)
    n = solve_on_model._cache_size()
    res = solve_on_model(_affine_model(0.9 * A, 2 * B, np.ones(NX)), task, jnp.ones((T, NU)), params)
    jax.block_until_ready(res.U)
    assert solve_on_model._cache_size() == n
