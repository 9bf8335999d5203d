"""The paper's claims about the local LTV regression, measured (analysis stage ``ltv``).

Section "Sampling Distributions and the Case for Linear Time-Varying Models": rollouts from
x0 + dx0 under U* + dU give, at every t, the regression dx_{t+1} ~ [A_t B_t] [dx_t; du_t]
whose Gram matrix dX_t' dX_t "is well-conditioned", whose right-hand side dX_t' dx_{t+1}
has "low" variance, and whose estimate is accurate whatever the sampling distribution.

Each of ``DISTRIBUTIONS`` draws the perturbations with the same per-coordinate standard
deviation (the solver's sigma_x, sigma_u) and the same number of rollouts R (the solver's
n_samples), K times with different seeds (analysis.n_datasets); all D x K x R rollouts are
one batch. Per (distribution, seed) this module measures, over t:
* the relative error of [A_t B_t] against central finite differences on the black box;
* the condition number of the Gram matrix, raw and scaled to a unit diagonal (the matrix
  the solver factorises; the SINDy Grams are given the same scaling in ``ill_conditioning``);
* across the K seeds, the spread of the error projections (1/R) dX_t' (dx_{t+1} - dX_t W_t)
  (W_t pooled over the seeds) relative to the right-hand side (1/R) dX_t' dx_{t+1}, the
  measure the SINDy variance stage takes of its projections.
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from mjx_surrogate.identification import sysid
from mjx_surrogate.linalg import relative_frobenius, unit_diagonal

DISTRIBUTIONS = ("gaussian", "uniform", "orthogonal")


def perturbations(kind: str, key: jax.Array, n: int, T: int, nx: int, nu: int, sx: float, su: float, dtype):
    """dx0 [n, nx], dU [n, T, nu], each coordinate of mean 0 and std (sx, su): ``gaussian``
    N(0, 1); ``uniform`` U(-sqrt 3, sqrt 3); ``orthogonal`` sqrt(n) times columns of
    Haar-random n x n orthogonal matrices (the QR of Gaussian ones, in float64 NumPy), one
    per t: across the n rollouts [dx0, du_0] are exactly orthogonal, and so are the
    columns of each du_t (n >= nx + nu)."""
    m = nx + nu
    if kind == "gaussian":
        z0 = jax.random.normal(key, (n, m), dtype)
        zu = jax.random.normal(jax.random.fold_in(key, 1), (n, T, nu), dtype)
    elif kind == "uniform":
        r = jnp.sqrt(3.0).astype(dtype)
        z0 = jax.random.uniform(key, (n, m), dtype, -r, r)
        zu = jax.random.uniform(jax.random.fold_in(key, 1), (n, T, nu), dtype, -r, r)
    elif kind == "orthogonal":
        if n < m:
            raise ValueError(f"n_samples: the orthogonal design needs >= nx + nu = {m}, got {n}")
        g = np.asarray(jax.random.normal(key, (T, n, n), jnp.float64 if jax.config.x64_enabled else None))
        q, r = np.linalg.qr(g.astype(np.float64))
        q = q * np.sign(np.diagonal(r, axis1=1, axis2=2))[:, None, :]  # Haar: the QR's signs fixed
        z0 = jnp.asarray(np.sqrt(n) * q[0, :, :m], dtype)
        zu = jnp.asarray(np.sqrt(n) * np.swapaxes(q[:, :, :nu], 0, 1), dtype)  # [n, T, nu]
    else:
        raise ValueError(f"distribution: {kind!r} is not one of {DISTRIBUTIONS}")
    dU = (su * zu).at[:, 0].set(su * z0[:, nx:])
    return sx * z0[:, :nx], dU


@partial(jax.jit, static_argnums=0)
def _regressions(system, X, U, dx0, dU):
    """dx0 [B, n, nx], dU [B, n, T, nu] (B = distributions x seeds) -> per B and t: A, B
    estimates, the regressors Z [B, T, n, m] and responses Y [B, T, n, nx]."""
    Bn = dx0.shape[:2]
    Xp = system.rollout((X[0] + dx0).reshape(-1, X.shape[-1]), (U + dU).reshape(-1, *U.shape))
    dX = Xp.reshape(*Bn, *X.shape) - X

    def one(dX, dU):
        Z = jnp.swapaxes(jnp.concatenate([dX[:, :-1], dU], -1), 0, 1)  # [T, n, m]
        G, F = sysid.normal_equations(Z, jnp.swapaxes(dX[:, 1:], 0, 1), None)
        A, Bm = sysid.solve_normal_equations(G, F, X.shape[-1])
        return A, Bm, Z, jnp.swapaxes(dX[:, 1:], 0, 1)

    return jax.vmap(one)(dX, dU)


def _conditions(G: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Condition numbers [..., T] of the Grams G [..., T, m, m], raw and at a unit diagonal."""
    flat = G.reshape(-1, *G.shape[-2:])
    scaled = unit_diagonal(flat)[0]  # NumPy in, NumPy at its precision out

    def cond(M):
        w = np.linalg.eigvalsh(M.astype(np.float64))
        return np.where(w[:, 0] > 0, w[:, -1] / np.maximum(w[:, 0], 1e-300), np.inf)

    return cond(flat).reshape(G.shape[:-2]), cond(scaled).reshape(G.shape[:-2])


def projection_spread(Z: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """Z [K, T, n, m], Y [K, T, n, nx] (K seeds) -> [T]: the mean over entries of the std
    across seeds of the error projections (1/n) Z_k' (Y_k - Z_k W), W the least squares
    pooled over the seeds, over the mean |(1/n) Z_k' Y_k| (float64)."""
    Z, Y = Z.astype(np.float64), Y.astype(np.float64)
    K, T, n, m = Z.shape
    out = np.empty(T)
    for t in range(T):
        W = np.linalg.lstsq(Z[:, t].reshape(K * n, m), Y[:, t].reshape(K * n, -1), rcond=None)[0]
        D = np.einsum("kni,knj->kij", Z[:, t], Y[:, t] - Z[:, t] @ W) / n
        rhs = np.einsum("kni,knj->kij", Z[:, t], Y[:, t]) / n
        out[t] = D.std(0).mean() / max(np.abs(rhs.mean(0)).mean(), 1e-300)
    return out


def _interval(v: np.ndarray) -> list[float]:
    """[min, max] over seeds: with 5 seeds the widest band they give."""
    return [float(np.min(v)), float(np.max(v))]


def distributions(n_samples: int, nx: int, nu: int) -> list[str]:
    """The distributions measurable at n_samples: the orthogonal design needs
    n_samples >= nx + nu; below, it is left out (and ``measure`` says so)."""
    return [k for k in DISTRIBUTIONS if k != "orthogonal" or n_samples >= nx + nu]


def measure(
    system, X_star, U_star, key, n_seeds: int, n_samples: int, sigma_x: float, sigma_u: float
) -> tuple[dict, dict]:
    """The module's measurements at the optimum X_star [T+1, nx], U_star [T, nu]: metrics
    per distribution (medians over seeds with their [min, max]) and arrays."""
    T, nu = U_star.shape
    nx = X_star.shape[-1]
    dt = X_star.dtype
    kinds = distributions(n_samples, nx, nu)
    keys = {kind: jax.random.fold_in(key, d) for d, kind in enumerate(DISTRIBUTIONS)}
    draws = [
        perturbations(kind, jax.random.fold_in(keys[kind], k), n_samples, T, nx, nu, sigma_x, sigma_u, dt)
        for kind in kinds
        for k in range(n_seeds)
    ]
    dx0 = jnp.stack([a for a, _ in draws])
    dU = jnp.stack([b for _, b in draws])
    A, B, Z, Y = (np.asarray(a) for a in _regressions(system, X_star, U_star, dx0, dU))
    G = np.einsum("btni,btnj->btij", Z, Z) / n_samples
    A_ref, B_ref = sysid.finite_difference_jacobians(system.step, X_star, U_star)
    W_ref = jnp.concatenate([A_ref, B_ref], -1)
    W = np.concatenate([A, B], -1)
    err = np.asarray(relative_frobenius(jnp.asarray(W), W_ref[None]))  # [D*K, T]
    raw, scaled = _conditions(G)  # [D*K, T]
    shape = (len(kinds), n_seeds)
    err, raw, scaled = (a.reshape(*shape, T) for a in (err, raw, scaled))
    Z, Y = Z.reshape(*shape, *Z.shape[1:]), Y.reshape(*shape, *Y.shape[1:])  # [D, K, T, n, .]
    out = {}
    for d, kind in enumerate(kinds):
        e = np.median(err[d], axis=1)  # per seed, the median over t
        c = np.median(scaled[d], axis=1)
        cmax = np.max(scaled[d], axis=1)
        craw = np.median(raw[d], axis=1)
        spread = projection_spread(Z[d], Y[d])
        out[kind] = {
            "model_error": float(np.median(e)),
            "model_error_interval": _interval(e),
            "condition_unit_diagonal": float(np.median(c)),
            "condition_unit_diagonal_interval": _interval(c),
            "condition_unit_diagonal_worst_t": float(np.max(cmax)),
            "condition_raw": float(np.median(craw)),
            "projection_spread": float(np.median(spread)),  # median over t
            "projection_spread_worst_t": float(np.max(spread)),
        }
    out["_setup"] = {
        "n_samples": n_samples,
        "n_seeds": n_seeds,
        "sigma_x": float(sigma_x),
        "sigma_u": float(sigma_u),
        "reference": "central finite differences on the black box (sysid.finite_difference_jacobians)",
        "interval": "[min, max] over the seeds of each seed's median over t",
        "left_out": [f"{k}: needs n_samples >= nx + nu = {nx + nu}" for k in DISTRIBUTIONS if k not in kinds],
    }
    return out, {"ltv_model_error": err, "ltv_condition_unit_diagonal": scaled, "ltv_condition_raw": raw}
