"""Reduced-order LTV identification (RO-D2C): a snapshot basis, then least squares in it.

For a black box with many states (a discretised PDE) the full-order schemes need at least
nx + nu samples per time step and an (nx + nu)-square regression. Around a nominal X
[T+1, nx], U [T, nu] the states that control perturbations reach span far fewer
directions. Following the method of snapshots of reduced-order iLQR (Sharma and
Chakravorty, ACC 2023, arXiv 2501.06635), with this module's notation:

1. snapshots: n rollouts from X[0] under U + dU (dU ~ N(0, sigma_u^2)), their deviations
   dX_i = X^(i) - X [n, T+1, nx];
2. basis: for each t, the left singular vectors V_t [nx, n] of [dX_1,t ... dX_n,t], keeping
   the leading ones that hold a fraction 1 - rank_tol of the snapshots' energy (sum of
   squared singular values) and zeroing the rest: r_t = rank of V_t <= n;
3. model: with alpha_t = V_t' dx_t, one step from (x_t +- V_t da, u_t +- du) at every t
   (an orthogonal design of n + nu samples: a diagonal Gram matrix) and the regression of
   V_{t+1}' (f+ - f-) / 2 on [da, du]:

       alpha_{t+1} ~= A_t alpha_t + B_t du_t,   A_t [n, n], B_t [n, nu].

n T rollout steps plus 2 (n + nu) T one-step calls, against 2 n_full T with n_full >= nx +
nu for the full-order central scheme. The solver runs its backward pass in these
coordinates (:mod:`mjx_surrogate.control.ilqr`, ``Problem.model_rank``): the cost's derivatives
are projected on V_t and the gains K_t = K^alpha_t V_t' lifted back. On a linear black box
the model is exact: A_t = V_{t+1}' A V_t, B_t = V_{t+1}' B.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax.sharding import Mesh

from mjx_surrogate import sharding
from mjx_surrogate.identification import sysid as sid


def snapshot_basis(dX: jax.Array, rank_tol: float) -> jax.Array:
    """dX [n, T+1, nx] -> V [T+1, nx, n]: per t, the leading left singular vectors of the
    snapshots dX[:, t] holding 1 - rank_tol of their energy; the other columns are zero
    (a zero snapshot set gives V_t = 0)."""

    def one(S):  # S [n, nx]
        W, s, _ = jnp.linalg.svd(S.T, full_matrices=False)  # W [nx, n], s [n] descending
        energy = s * s
        total = jnp.sum(energy)
        before = jnp.cumsum(energy) - energy  # energy of the modes ahead of each
        keep = (before < (1.0 - rank_tol) * total) & (s > 0)
        return W * keep[None, :].astype(W.dtype)

    return jax.lax.map(one, jnp.swapaxes(dX, 0, 1))


def basis_rank(V: jax.Array) -> jax.Array:
    """r_t [T+1]: the number of basis vectors kept at each t."""
    return jnp.sum(jnp.any(V != 0, axis=-2), axis=-1)


def project(V: jax.Array, dX: jax.Array) -> jax.Array:
    """alpha [..., T+1, n] = V_t' dX_t for deviations dX [..., T+1, nx]."""
    return jnp.einsum("...tn,tnr->...tr", dX, V)


def lift_model(A: jax.Array, B: jax.Array, V: jax.Array) -> tuple[jax.Array, jax.Array]:
    """The full-order model of a reduced one: V_{t+1} A_t V_t' [T, nx, nx], V_{t+1} B_t."""
    return jnp.einsum("tir,trs,tjs->tij", V[1:], A, V[:-1]), jnp.einsum("tir,trk->tik", V[1:], B)


def project_model(A: jax.Array, B: jax.Array, V: jax.Array) -> tuple[jax.Array, jax.Array]:
    """A full-order model [T, nx, nx], [T, nx, nu] in the basis V [T+1, nx, r]: V_{t+1}' A_t
    V_t [T, r, r], V_{t+1}' B_t [T, r, nu] (what a reduced model of a linear system equals)."""
    return jnp.einsum("tnr,tnm,tms->trs", V[1:], A, V[:-1]), jnp.einsum("tnr,tnk->trk", V[1:], B)


def fit_in_snapshot_basis(
    dX: jax.Array, dU: jax.Array, rank_tol: float
) -> tuple[jax.Array, jax.Array, jax.Array]:
    """The LTV model of deviation trajectories dX [n, T+1, nx], dU [n, T, nu] in their own
    per-t snapshot basis V (:func:`snapshot_basis`): the regression of alpha_{t+1} on
    [alpha_t, du_t], alpha_t = V_t' dx_t; returns A [T, n, n], B [T, n, nu], V [T+1, nx, n].
    Where the trajectories span fewer than nx directions at t (data around a nominal from a
    fixed start span at most nu t), the full-order regression is rank-deficient; this one
    is not."""
    V = snapshot_basis(dX, rank_tol)
    A, B = sid.fit_from_trajectories(project(V, dX), dU)
    kept = jnp.any(V != 0, axis=-2).astype(A.dtype)  # [T+1, n]
    return A * kept[:-1, None, :] * kept[1:, :, None], B * kept[1:, :, None], V


def snapshots(
    rollout, X: jax.Array, U: jax.Array, key: jax.Array, n: int, sigma_u: float, mesh: Mesh | None = None
) -> jax.Array:
    """dX [n, T+1, nx]: deviations of n rollouts from X[0] under U + dU from X."""
    dU = sigma_u * jax.random.normal(key, (n,) + U.shape, U.dtype)

    def deviations(dU, X, U):
        return rollout(jnp.broadcast_to(X[0], (dU.shape[0],) + X[0].shape), U[None] + dU) - X[None]

    return sharding.map_batch(deviations, mesh, dU, rest=(X, U))


def reduced_central_difference(
    system, X: jax.Array, U: jax.Array, key: jax.Array, p: sid.SysIdParams
) -> tuple[jax.Array, jax.Array, jax.Array]:
    """The scheme of the module docstring around X [T+1, nx], U [T, nu]: A [T, n, n], B [T,
    n, nu], V [T+1, nx, n] with n = ``p.n_samples`` snapshots (the largest rank)."""
    T, nu = U.shape
    nx, n = X.shape[-1], p.n_samples
    mesh = sid._mesh(system)
    k_snap, k_design = jax.random.split(key)
    V = snapshot_basis(snapshots(system.rollout, X, U, k_snap, n, p.sigma_u, mesh), p.rank_tol)
    m = n + nu
    scale = jnp.concatenate([jnp.full(n, p.sigma_x, X.dtype), jnp.full(nu, p.sigma_u, X.dtype)])
    Z = jnp.swapaxes(sid.orthogonal_design(k_design, T, m, m, X.dtype) * scale, 0, 1)  # [m, T, m]
    if not p.perturb_x0:  # x_0 is given: identify B_0 alone
        Z = Z.at[:, 0, :n].set(0.0)

    def stats(Z, w, X, U, V):
        z = jnp.swapaxes(Z, 0, 1)  # [T, b, m]
        b = z.shape[1]

        def at(args):  # one time step: V_t' (f+ - f-) / 2 [b, r] of its b samples
            x, u, zt, W, W_next = args
            dx = zt[:, :n] @ W.T  # [b, nx]
            xs = jnp.concatenate([x + dx, x - dx])
            us = jnp.concatenate([u + zt[:, n:], u - zt[:, n:]])
            f = jax.vmap(system.step)(xs, us)
            return (0.5 * (f[:b] - f[b:])) @ W_next

        y = sharding.vmap_in_chunks(at, (X[:-1], U, z, V[:-1], V[1:]), 2 * b * nx)  # [T, b, r]
        return sid.normal_equations(z, y, w, diagonal=True)

    G, F = sharding.sum_over_batch(stats, mesh, Z, (X, U, V))
    A, B = sid.solve_normal_equations(G, F, n)
    kept = jnp.any(V != 0, axis=-2).astype(A.dtype)  # [T+1, n]
    return A * kept[:-1, None, :] * kept[1:, :, None], B * kept[1:, :, None], V


sid.register_scheme(
    "reduced",
    sid.IdentificationScheme(
        lambda system, p: lambda X, U, K, key: reduced_central_difference(system, X, U, key, p),
        lambda T, n, nu: n * T + 2 * (n + nu) * T,
        "RO-D2C: a snapshot basis of n rollouts, central differences in it",
        reduced=True,
    ),
)
