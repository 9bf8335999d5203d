"""Identification at every k-th time step, linear interpolation between (``sysid.every``).

A one-step scheme identifies (A_t, B_t) at each t from its own samples. Along a smooth
nominal the Jacobians change slowly in t, so they can be identified only at the knots
S = {0, k, 2k, ...} plus the last step T-1 and interpolated linearly in between (MuJoCo
MPC's iLQG does the same with its finite differences). One identification then simulates
|S| / T of the scheme's steps: about 1/k.

Notation: T steps, knots S [m] (sorted, S[0] = 0, S[-1] = T-1), values at the knots
V_S [m, ...] -> V [T, ...].
"""

from __future__ import annotations

from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np

# linearize(X [T+1, nx], U [T, nu], K [T, nu, nx], key) -> (A [T, nx, nx], B [T, nx, nu])
LinearizeFn = Callable[[jax.Array, jax.Array, jax.Array, jax.Array], tuple[jax.Array, jax.Array]]


def knot_times(T: int, every: int) -> np.ndarray:
    """Every ``every``-th step from 0, and the last step T-1: int [m] (static)."""
    S = np.arange(0, T, every)
    return S if S[-1] == T - 1 else np.append(S, T - 1)


def interpolate(V_S: jax.Array, S: np.ndarray, T: int) -> jax.Array:
    """Piecewise-linear in t through the knots: V_S [m, ...] at times S -> [T, ...]."""
    t = np.arange(T)
    right = np.clip(np.searchsorted(S, t, side="left"), 1, len(S) - 1)  # S[right-1] < t <= S[right]
    left = right - 1
    w = (t - S[left]) / np.maximum(S[right] - S[left], 1)
    w = jnp.asarray(w, V_S.dtype).reshape((T,) + (1,) * (V_S.ndim - 1))
    if len(S) == 1:
        return jnp.broadcast_to(V_S[:1], (T,) + V_S.shape[1:])
    return (1 - w) * V_S[left] + w * V_S[right]


def at_knots(linearize: LinearizeFn, every: int) -> LinearizeFn:
    """``linearize`` (a one-step scheme's) run at the knots only, interpolated in t."""
    if every == 1:
        return linearize

    def knotted(X, U, K, key):
        T = U.shape[0]
        S = knot_times(T, every)
        Xs = jnp.concatenate([X[S], X[-1:]])  # one-step schemes read X[:-1] only
        A_S, B_S = linearize(Xs, U[S], K[S], key)
        return interpolate(A_S, S, T), interpolate(B_S, S, T)

    return knotted


def identifications_per_iteration(T: int, every: int) -> int:
    """How many time steps one identification simulates: |S|."""
    return int(knot_times(T, every).size)
