"""Gram matrices of the fitted models and the spread of the normal equations' terms.

SINDy: G = (1/R) Theta' Theta [P, P]; its eigenvalues (= squared singular values of
Theta / sqrt(R)) and condition number (paper, "Ill-conditioning").

MLP (paper, "The Nonlinear Case"): with h(z, theta) the network in standardised units and
H = dh/dtheta [R nx, n_theta] on R points, the Gauss-Newton Gram (1/R) H' H and the
descent direction (1/R) H' Delta, Delta = y - h(z, theta) (the negative loss gradient up
to a factor 2). Everything here is evaluated in the dtype of its inputs: pass float64
(``jax_enable_x64``) for condition numbers beyond ~1e7.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from flax import nnx
from jax.flatten_util import ravel_pytree

from mjx_surrogate.surrogates.mlp import MLPModel


def eigenvalues(G: jax.Array) -> np.ndarray:
    """Eigenvalues of a symmetric PSD matrix, descending, as float64 NumPy."""
    w = np.linalg.eigvalsh(np.asarray(G, np.float64))[::-1]
    return np.maximum(w, 0.0)


def condition(eigs: np.ndarray) -> float:
    """lambda_max / lambda_min (inf if singular to working precision)."""
    return float(eigs[0] / eigs[-1]) if eigs[-1] > 0 else float("inf")


def _flat_apply(model: MLPModel):
    """(theta_flat [n_theta], zs [nz] standardised) -> h [nx] standardised; and theta0."""
    flat, unravel = ravel_pytree(model.params)

    def h(theta, zs):
        return nnx.merge(model.graphdef, unravel(theta))(zs)

    return h, flat


def standardise(model: MLPModel, z: jax.Array, y: jax.Array) -> tuple[jax.Array, jax.Array]:
    n = model.norm
    return ((z - n.z_mean) / n.z_std).astype(jnp.float32), ((y - n.y_mean) / n.y_std).astype(jnp.float32)


def mlp_jacobian(model: MLPModel, zs: jax.Array, dtype=jnp.float64) -> jax.Array:
    """H [R * nx, n_theta]: d h(z_i, theta) / d theta stacked over the points zs [R, nz]."""
    h, flat = _flat_apply(model)
    J = jax.vmap(jax.jacrev(h), in_axes=(None, 0))(flat, zs)  # [R, nx, n_theta]
    return J.reshape(-1, flat.shape[0]).astype(dtype)


def mlp_gram(model: MLPModel, zs: jax.Array) -> jax.Array:
    """(1/R) H' H [n_theta, n_theta] in float64 where enabled."""
    H = mlp_jacobian(model, zs, jnp.result_type(float))
    return H.T @ H / zs.shape[0]


def mlp_descent_direction(model: MLPModel, zs: jax.Array, ys: jax.Array) -> jax.Array:
    """(1/R) H' Delta [n_theta], Delta = ys - h(zs) (both standardised)."""
    h, flat = _flat_apply(model)
    H = mlp_jacobian(model, zs, jnp.result_type(float))
    delta = (ys - jax.vmap(h, in_axes=(None, 0))(flat, zs)).reshape(-1).astype(H.dtype)
    return H.T @ delta / zs.shape[0]


def error_projections(thetas: list[jax.Array], ys: list[jax.Array], coef: jax.Array) -> jax.Array:
    """(1/R_s) Theta_s' (Y_s - Theta_s C) for data sets s = 1..S: [S, P, nx].

    With C fitted on the pooled data, these are the fluctuations delta^R of the normal
    equations' right-hand side from one data set to the next (zero on average)."""
    return jnp.stack([t.T @ (y - t @ coef) / t.shape[0] for t, y in zip(thetas, ys)])


def cosine_matrix(V: np.ndarray) -> np.ndarray:
    """Pairwise cosine similarities of the rows of V [S, n]."""
    V = np.asarray(V, np.float64)
    n = np.linalg.norm(V, axis=1, keepdims=True)
    U = V / np.where(n > 0, n, 1.0)
    return U @ U.T
