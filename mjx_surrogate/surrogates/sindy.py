"""Linear-in-parameters (SINDy-style) discrete-time models x_{t+1} = Theta(x_t, u_t) C.

With R transitions stacked, Theta [R, P] and targets Y [R, nx], the normal equations
(paper, "Data Driven Solutions") read

    G C = b,    G = (1/R) Theta' Theta [P, P]  (the Gram matrix),
                b = (1/R) Theta' Y     [P, nx] (the projections of the data on the basis).

``fit`` solves them after scaling every column of Theta to unit 2-norm (the scale is
undone on C), either by elimination on G or by an SVD least-squares solve of the scaled
Theta (better conditioned: cond(Theta) = sqrt(cond(G))). ``stlsq`` is sequentially
thresholded least squares with pysindy's semantics: ridge (alpha) solves on the active
columns, coefficients with |c| < threshold dropped until the support stops changing,
then an unregularised refit on the final support. Use float64 (``jax_enable_x64``) for
degree >= 4 libraries: their Gram matrices pass what float32 can resolve.
"""

from __future__ import annotations

from functools import partial
from typing import Literal

import jax
import jax.numpy as jnp
from flax import struct

from mjx_surrogate.linalg import spd_solve
from mjx_surrogate.surrogates import library
from mjx_surrogate.surrogates.library import LibrarySpec


@struct.dataclass
class SindyModel:
    coef: jax.Array  # [P, nx]
    spec: LibrarySpec = struct.field(pytree_node=False)
    increment: bool = struct.field(pytree_node=False, default=False)  # predicts x_{t+1} - x_t

    def step(self, x: jax.Array, u: jax.Array) -> jax.Array:
        """x [nx], u [nu] -> x_next [nx] (any leading batch axes)."""
        theta = library.features(self.spec, jnp.concatenate([x, u], axis=-1))
        out = theta @ self.coef
        return x + out if self.increment else out


@partial(jax.jit, static_argnums=0)  # eager, each block would compile on its own
def design(spec: LibrarySpec, x: jax.Array, u: jax.Array) -> jax.Array:
    """Theta [R, P] from states x [R, nx] and controls u [R, nu]."""
    return library.features(spec, jnp.concatenate([x, u], axis=-1))


def gram(theta: jax.Array) -> jax.Array:
    """G = (1/R) Theta' Theta [P, P]."""
    return theta.T @ theta / theta.shape[0]


def projections(theta: jax.Array, y: jax.Array) -> jax.Array:
    """b = (1/R) Theta' y [P, k] (of the targets, or of the residual for the variance study)."""
    return theta.T @ y / theta.shape[0]


def _column_norms(theta: jax.Array) -> jax.Array:
    n = jnp.linalg.norm(theta, axis=0)
    return jnp.where(n > 0, n, 1.0)


@partial(jax.jit, static_argnames=("method",))
def lstsq(theta: jax.Array, y: jax.Array, method: Literal["svd", "normal"] = "svd") -> jax.Array:
    """Least-squares C [P, k] for Theta [R, P] C ~ y [R, k], columns scaled to unit norm."""
    s = _column_norms(theta)
    ts = theta / s
    if method == "svd":
        c = jnp.linalg.lstsq(ts, y)[0]
    else:
        c, _ = spd_solve(ts.T @ ts, ts.T @ y)
    return c / s[:, None]


def _masked_solve(g: jax.Array, r: jax.Array, mask: jax.Array, alpha: float) -> jax.Array:
    """Solve (G + alpha I) c = r on the columns in ``mask``; c = 0 off the mask."""
    m = mask.astype(g.dtype)
    a = g * m[:, None] * m[None, :] + jnp.diag(alpha * m + (1.0 - m))
    c, _ = spd_solve(a, (r * m)[:, None])
    return c[:, 0] * m


@partial(jax.jit, static_argnames=("max_iter", "normalize_columns"))
def stlsq(
    theta: jax.Array,
    y: jax.Array,
    threshold: float,
    alpha: float = 0.05,
    max_iter: int = 20,
    normalize_columns: bool = False,
) -> jax.Array:
    """Sequentially thresholded least squares: C [P, k] with pysindy's STLSQ semantics.

    The threshold applies to the (column-normalised, if asked) coefficients; the ridge
    term is alpha |c|^2 on the unnormalised residual sum of squares, as in pysindy.
    """
    s = _column_norms(theta) if normalize_columns else jnp.ones(theta.shape[1], theta.dtype)
    ts = theta / s
    g, r = ts.T @ ts, ts.T @ y  # [P, P], [P, k]

    def one_target(r_k):
        def body(_, mask):
            c = _masked_solve(g, r_k, mask, alpha)
            return mask & (jnp.abs(c) >= threshold)

        mask0 = jnp.ones(g.shape[0], bool)
        mask = jax.lax.fori_loop(0, max_iter, body, mask0)
        c = _masked_solve(g, r_k, mask, alpha)  # the last thresholded iterate's support
        support = mask & (jnp.abs(c) >= threshold)
        return _masked_solve(g, r_k, support, 0.0)  # unbias: plain least squares

    c = jax.vmap(one_target, in_axes=1, out_axes=1)(r)
    return c / s[:, None]


def fit(
    spec: LibrarySpec,
    x: jax.Array,
    u: jax.Array,
    x_next: jax.Array,
    *,
    increment: bool = False,
    threshold: float = 0.0,
    alpha: float = 0.0,
    method: Literal["svd", "normal"] = "svd",
    max_iter: int = 20,
) -> SindyModel:
    """Fit a SINDy model on transitions; threshold > 0 selects STLSQ."""
    theta = design(spec, x, u)
    y = x_next - x if increment else x_next
    if threshold > 0:
        coef = stlsq(theta, y, threshold, alpha, max_iter, normalize_columns=True)
    else:
        coef = lstsq(theta, y, method)
    return SindyModel(coef, spec, increment)
