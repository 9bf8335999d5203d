"""Small dense solves in plain JAX ops (no LAPACK custom calls).

jaxlib 0.10's batched LAPACK kernels split their batch over XLA's CPU thread pool from
inside a thread of that pool and wait on it; when all pool threads run such kernels at
once the process deadlocks (docs/performance.md, "No LAPACK in compiled programs"). The
solver and the LTV fit run inside vmaps and loops and only need small symmetric
positive-definite systems, solved here by elimination, so they never emit a batched LAPACK
call.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np


def spd_solve(A: jax.Array, B: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Solve A X = B for small symmetric A [n, n] by Gauss-Jordan elimination without
    pivoting; returns (X, ok) with ok = all pivots > 0, i.e. A positive definite.

    A [n, n], B [n] or [n, k]; n is small (a control or regressor dimension).
    """
    n = A.shape[0]
    vec = B.ndim == 1
    M = jnp.concatenate([A, B[:, None] if vec else B], axis=1)

    def body(i, carry):
        M, ok = carry
        piv = M[i, i]
        ok = ok & (piv > 0)
        row = M[i] / jnp.where(piv != 0, piv, 1.0)
        col = M[:, i].at[i].set(0.0)
        M = M - col[:, None] * row[None, :]
        return M.at[i].set(row), ok

    # Unrolled for small n: inside the Riccati scan a loop's per-iteration cost dominated
    # (backward pass 10-16 % faster at T 600-800, nu 5; benchmarks/backward_pass.py).
    M, ok = jax.lax.fori_loop(0, n, body, (M, jnp.array(True)), unroll=n <= 16)
    X = M[:, n:]
    return (X[:, 0] if vec else X), ok & jnp.all(jnp.isfinite(X))


def unit_diagonal(G: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
    """Gram matrices G [T, m, m] scaled to a unit diagonal: (Gs, s, moved) with
    G = diag(s) Gs diag(s); a zero diagonal entry (a regressor that never moved) keeps
    s = 1 and gets a unit diagonal in Gs, so its coefficient solves to 0. A NumPy G is
    scaled in NumPy at its own precision (the analysis' float64 SINDy Grams)."""
    xp = np if isinstance(G, np.ndarray) else jnp
    d = xp.diagonal(G, axis1=1, axis2=2)  # [T, m]
    moved = d > 0
    s = xp.where(moved, xp.sqrt(xp.where(moved, d, 1.0)), 1.0)
    eye = xp.eye(G.shape[-1], dtype=G.dtype)
    Gs = G / (s[:, :, None] * s[:, None, :]) + eye * (~moved).astype(G.dtype)[:, None, :]
    return Gs, s, moved


def relative_frobenius(M: jax.Array, M_ref: jax.Array) -> jax.Array:
    """||M_t - M_ref_t||_F / ||M_ref_t||_F per leading index: [T, a, b] -> [T]
    (the denominator floored at 1e-12)."""
    ref = jnp.linalg.norm(M_ref, axis=(-2, -1))
    return jnp.linalg.norm(M - M_ref, axis=(-2, -1)) / jnp.maximum(ref, 1e-12)


def ltv_relative_error(A: jax.Array, B: jax.Array, A_ref: jax.Array, B_ref: jax.Array) -> jax.Array:
    """||[A_t B_t] - [A*_t B*_t]||_F / ||[A*_t B*_t]||_F: A [T, nx, nx], B [T, nx, nu] -> [T]."""
    return relative_frobenius(jnp.concatenate([A, B], -1), jnp.concatenate([A_ref, B_ref], -1))
