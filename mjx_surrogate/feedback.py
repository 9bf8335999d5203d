"""Closed-loop evaluation of an iLQR solution under process noise."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp

from mjx_surrogate.systems import System
from mjx_surrogate.tasks import Task, trajectory_cost


@functools.partial(jax.jit, static_argnames=("system", "n_trials"))
def evaluate_feedback(system: System, task: Task, X: jax.Array, U: jax.Array, K: jax.Array,
                      noise_levels: jax.Array, key: jax.Array, n_trials: int):
    """Cost of u_t = U_t + K_t (x_t - X_t) + w_t (closed loop) and U_t + w_t (open loop).

    w_t ~ N(0, (level * max|U|)^2) per channel, the same draws for both policies.
    X [T+1, nx], U [T, nu], K [T, nu, nx], noise_levels [L] -> two cost arrays [L, n_trials].
    """
    L = noise_levels.shape[0]
    T, nu = U.shape
    u_scale = jnp.max(jnp.abs(U), axis=0) + 1e-12  # [nu]
    W = jax.random.normal(key, (L, n_trials, T, nu), U.dtype)
    W = W * noise_levels[:, None, None, None] * u_scale

    def run(w, gain):
        def body(x, inp):
            xb, ub, Kt, wt = inp
            u = jnp.clip(ub + gain * (Kt @ (x - xb)) + wt, task.u_min, task.u_max)
            return system.step(x, u), (x, u)

        xT, (Xs, Us) = jax.lax.scan(body, task.x0, (X[:-1], U, K, w))
        return trajectory_cost(task, jnp.concatenate([Xs, xT[None]]), Us)

    flat = W.reshape(L * n_trials, T, nu)
    closed = jax.vmap(run, in_axes=(0, None))(flat, 1.0).reshape(L, n_trials)
    opened = jax.vmap(run, in_axes=(0, None))(flat, 0.0).reshape(L, n_trials)
    return closed, opened
