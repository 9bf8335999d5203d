"""How local a data set is: the quantity the paper's argument rests on.

The paper's claim is that a global surrogate fitted to data *around* an optimum fails
where the local LTV model does not. It is testable only if the data stayed near the
optimum. Two measures:

* ``relative_spread`` of a data set X [N, T+1, nx] around the optimum X* [T+1, nx]: for
  each trajectory the largest deviation max_t ||x_t - x*_t|| divided by the optimum's own
  excursion max_t ||x*_t - x*_0||; the median over trajectories (a blown-up trajectory
  counts as +inf). Well below 1: the data hug the optimum. About 1 or more: the
  perturbed trajectories move as far from the optimum as the whole manoeuvre does, and
  no model is "local" there.
* ``open_loop_gain`` of the optimum's linearisation (A_t, B_t): the RMS terminal deviation
  caused by unit white control noise at every step, sqrt(trace P_T / (T nu)), with
  P_{t+1} = A_t P_t A_t' + B_t B_t', P_0 = 0. It says how strongly the open-loop system
  amplifies perturbations along this trajectory (unstable optima have large gains, and
  their data sets leave the neighbourhood at small levels).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp


@jax.jit
def relative_spread(X: jax.Array, X_star: jax.Array) -> jax.Array:
    """Median over trajectories of max_t ||x_t - x*_t|| / max_t ||x*_t - x*_0||;
    X [N, T+1, nx], X* [T+1, nx]. Non-finite trajectories count as +inf."""
    dev = jnp.linalg.norm(X - X_star[None], axis=-1).max(axis=1)  # [N]
    dev = jnp.where(jnp.isfinite(dev), dev, jnp.inf)
    excursion = jnp.linalg.norm(X_star - X_star[0], axis=-1).max()
    return jnp.median(dev) / jnp.maximum(excursion, jnp.finfo(X_star.dtype).tiny)


def open_loop_gain(A: jax.Array, B: jax.Array) -> jax.Array:
    """sqrt(trace P_T / (T nu)) for P_{t+1} = A_t P_t A_t' + B_t B_t', P_0 = 0;
    A [T, nx, nx], B [T, nx, nu]."""
    T, nx, nu = B.shape

    def step(P, AB):
        At, Bt = AB
        return At @ P @ At.T + Bt @ Bt.T, None

    P, _ = jax.lax.scan(step, jnp.zeros((nx, nx), A.dtype), (A, B))
    return jnp.sqrt(jnp.trace(P) / (T * nu))
