"""Which identified coefficients the data can tell from zero: a t-test on the LTV regression.

For each t and output row i the least-squares estimate w_ij of [A_t B_t] has the standard
error (ordinary least squares, notation of :mod:`mjx_surrogate.identification.sysid`)

    se_ij = sqrt( RSS_i / (n - m) * (G^-1)_jj ),    RSS_i = sum_k y_ki^2 - w_i' F_i,

with n samples, m regressors that moved (nx + nu, or fewer where a coordinate was not
perturbed) and G = Z'Z, F = Z'Y. Coefficients with |w_ij| <= t_min se_ij are set to zero.

Why: a row that is linear at the perturbation scale has a residual at round-off level, so
every coefficient that matters is many standard errors from zero and is kept. A row that
is not (a contact event inside the step: the response jumps with the perturbation) leaves
a large residual, and least squares spreads that residual over every regressor, controls
included: on the dm_control manipulator, its free-falling objects (which no control can
move) identified with control gains up to 3e4, against exactly 0 by central differences
along each coordinate, and the value function carried them into the arm's gains; D2C
stalled at 2.5x the oracle's cost. With the test it reaches the oracle's cost in the
oracle's 11 iterations. ``sysid.significance`` is 3 by default on a user's model
with loose objects, trees no actuator moves (``model_defaults.default_significance``), and
off elsewhere: where a task is made of contacts (gymnasium's hopper and ant moving
forward) the rows fitted across contact events carry an averaged slope the solve needs,
and dropping its uncertain part cost the hopper 13 % and the ant its goal
(docs/performance.md). A sample
count of n <= m leaves no residual to test with: then nothing is zeroed.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from mjx_surrogate.linalg import spd_solve, unit_diagonal


def sum_of_squares(Y: jax.Array, w: jax.Array | None) -> jax.Array:
    """S [T, nx]: sum over samples of w y^2 for responses Y [T, n, nx] (w [n]; None: ones),
    the third sufficient statistic of the regression (summed over devices like G and F)."""
    if w is not None:
        keep = (w > 0)[None, :, None]
        Y = jnp.where(keep, Y, 0.0) * jnp.sqrt(jnp.where(keep, w[None, :, None], 0.0))
    return jnp.einsum("tni,tni->ti", Y, Y)


def gram_inverse_diagonal(G: jax.Array) -> tuple[jax.Array, jax.Array]:
    """diag(G^-1) [T, m] of G [T, m, m] (or of a diagonal Gram matrix given as [T, m]), and
    which regressors moved [T, m] (a zero diagonal entry: coefficient 0, not estimated)."""
    if G.ndim == 2:
        moved = G > 0
        return 1.0 / jnp.where(moved, G, 1.0), moved
    Gs, s, moved = unit_diagonal(G)
    eye = jnp.eye(G.shape[-1], dtype=G.dtype)
    inv = jax.vmap(lambda g: spd_solve(g, eye)[0])(Gs)
    return jnp.diagonal(inv, axis1=1, axis2=2) / s**2, moved


def drop_insignificant(
    G: jax.Array, F: jax.Array, S: jax.Array, A: jax.Array, B: jax.Array, n: int, t_min: float
) -> tuple[jax.Array, jax.Array]:
    """Zero the entries of A [T, nx, nx], B [T, nx, nu] whose |t| = |w| / se is at most
    ``t_min`` (module docstring); G [T, m, m] or [T, m], F [T, m, nx], S [T, nx] are the
    regression's sums over its n samples."""
    nx = A.shape[-1]
    W = jnp.concatenate([A, B], axis=-1)  # [T, nx, m]
    rss = jnp.maximum(S - jnp.einsum("tim,tmi->ti", W, F), 0.0)  # [T, nx]
    g_inv, moved = gram_inverse_diagonal(G)
    dof = n - jnp.sum(moved, axis=-1)  # [T]
    var = rss / jnp.maximum(dof, 1)[:, None]
    se = jnp.sqrt(var[:, :, None] * g_inv[:, None, :])  # [T, nx, m]
    keep = (jnp.abs(W) > t_min * se) | (dof <= 0)[:, None, None]
    W = jnp.where(keep, W, 0.0)
    return W[..., :nx], W[..., nx:]
