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

from functools import partial

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


def rank_and_condition(eigs: np.ndarray, rel: float) -> tuple[int, float]:
    """The numerical rank of a Gram (eigenvalues eigs, descending, above ``rel`` lambda_max;
    ``rel`` e.g. :func:`gram_rank_tolerance`) and the condition number of that part,
    lambda_max / the smallest of them: its conditioning apart from its exact null space (an
    MLP's hidden-unit scaling symmetries, or fewer data than parameters, make the whole Gram
    singular by construction)."""
    kept = eigs[eigs > rel * eigs[0]]
    return int(kept.size), float(kept[0] / kept[-1])


def _flat_apply(model: MLPModel, dtype=None):
    """(theta_flat [n_theta], zs [nz] standardised) -> h [nx] standardised; and theta0
    (the trained parameters, cast to ``dtype`` if given: the same network evaluated in it)."""
    params = model.params if dtype is None else jax.tree.map(lambda a: a.astype(dtype), model.params)
    flat, unravel = ravel_pytree(params)

    def h(theta, zs):
        return nnx.merge(model.graphdef, unravel(theta))(zs)

    return h, flat


def standardise(model: MLPModel, z: jax.Array, y: jax.Array) -> tuple[jax.Array, jax.Array]:
    n = model.norm
    return ((z - n.z_mean) / n.z_std).astype(jnp.float32), ((y - n.y_mean) / n.y_std).astype(jnp.float32)


@partial(jax.jit, static_argnames=("dtype", "evaluate_in"))
def mlp_jacobian(model: MLPModel, zs: jax.Array, dtype=jnp.float64, evaluate_in=None) -> jax.Array:
    """H [R * nx, n_theta]: d h(z_i, theta) / d theta stacked over the points zs [R, nz],
    computed in the network's own precision (or ``evaluate_in``), returned as ``dtype``."""
    h, flat = _flat_apply(model, evaluate_in)
    zs = zs if evaluate_in is None else zs.astype(evaluate_in)
    J = jax.vmap(jax.jacrev(h), in_axes=(None, 0))(flat, zs)  # [R, nx, n_theta]
    return J.reshape(-1, flat.shape[0]).astype(dtype)


@jax.jit
def mlp_gram(model: MLPModel, zs: jax.Array) -> jax.Array:
    """(1/R) H' H [n_theta, n_theta], the Jacobian evaluated at the trained parameters in
    float64 where enabled: the null space of the ReLU units' scaling symmetries is then exact
    to float64, not buried under float32 rounding (:func:`rank_and_condition`)."""
    H = mlp_jacobian(model, zs, jnp.result_type(float), evaluate_in=jnp.result_type(float))
    return H.T @ H / zs.shape[0]


def gram_rank_tolerance(n_rows: int, n_cols: int, dtype) -> float:
    """The relative eigenvalue below which a formed Gram H'H / R (H [n_rows, n_cols]) is
    singular at its precision: max(n_rows, n_cols) eps, the resolution of its eigenvalues
    (numpy's ``matrix_rank`` rule, applied to the Gram rather than to H)."""
    return float(max(n_rows, n_cols) * jnp.finfo(dtype).eps)


@jax.jit
def mlp_descent_direction(model: MLPModel, zs: jax.Array, ys: jax.Array) -> jax.Array:
    """(1/R) H' Delta [n_theta], Delta = ys - h(zs) (both standardised)."""
    h, flat = _flat_apply(model)
    H = mlp_jacobian(model, zs, jnp.result_type(float))
    delta = (ys - jax.vmap(h, in_axes=(None, 0))(flat, zs)).reshape(-1).astype(H.dtype)
    return H.T @ delta / zs.shape[0]


@jax.jit
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


def pairwise_cosines(V: np.ndarray) -> np.ndarray:
    """The cosines of the distinct (ordered) pairs of rows of V [S, n]: [S (S - 1)]."""
    C = cosine_matrix(V)
    return C[~np.eye(len(C), dtype=bool)]


def mean_pairwise_cosine(V: np.ndarray) -> float:
    """Mean cosine over the distinct pairs of rows of V [S, n]."""
    return float(pairwise_cosines(V).mean())


def pairwise_cosine_interval(V: np.ndarray, rng: np.random.Generator, n_boot: int = 1000) -> list[float]:
    """A 90 % bootstrap interval of :func:`mean_pairwise_cosine` over the S rows of V [S, n]:
    the rows resampled with replacement, each resample's mean taken over pairs of distinct
    draws (a row paired with its own copy would add a cosine of 1)."""
    C = cosine_matrix(V)
    S = len(C)
    boot = []
    for _ in range(n_boot):
        i = rng.integers(0, S, S)
        distinct = i[:, None] != i[None, :]
        if distinct.any():
            boot.append(C[np.ix_(i, i)][distinct].mean())
    return [float(np.quantile(boot, 0.05)), float(np.quantile(boot, 0.95))]
