"""Simulation of one-step maps: the open-loop scan and the feedback scan, shared by the
solver, the identification schemes, the data sets and every evaluation.

Notation (fixed for the module): a step is ``step(x[nx], u[nu]) -> x_next[nx]`` (a MuJoCo
backend, an LTV model or a surrogate); a time-indexed step is ``step_t(t, x, u)``. A
nominal is X_bar [T+1, nx], U_bar [T, nu]; a policy around it is

    u_t = clip(U_bar_t + v_t + K_t (x_t - X_bar_t), lo, hi)

with offsets v [T, nu] (the iLQR step alpha k, identification or process noise) and gains
K [T, nu, nx]. Batches lead: ``[B, ...]``.
"""

from __future__ import annotations

from typing import Callable

import jax
import jax.numpy as jnp

StepFn = Callable[[jax.Array, jax.Array], jax.Array]
StepTFn = Callable[[jax.Array, jax.Array, jax.Array], jax.Array]


def simulate_t(step_t: StepTFn, x0: jax.Array, U: jax.Array) -> jax.Array:
    """Open loop with a time-indexed step: x0 [nx], U [T, nu] -> X [T+1, nx]."""

    def body(x, tu):
        x_next = step_t(tu[0], x, tu[1])
        return x_next, x_next

    _, xs = jax.lax.scan(body, x0, (jnp.arange(U.shape[0]), U))
    return jnp.concatenate([x0[None], xs], axis=0)


def simulate(step: StepFn, x0: jax.Array, U: jax.Array) -> jax.Array:
    """Open loop: x0 [nx], U [T, nu] -> X [T+1, nx] by ``lax.scan``."""
    return simulate_t(lambda t, x, u: step(x, u), x0, U)


def simulate_batch(step: StepFn, x0: jax.Array, U: jax.Array) -> jax.Array:
    """x0 [B, nx], U [B, T, nu] -> X [B, T+1, nx] (vmap of :func:`simulate`)."""
    return jax.vmap(simulate, in_axes=(None, 0, 0))(step, x0, U)


def feedback_rollout(
    step: StepFn,
    x0: jax.Array,
    X_bar: jax.Array,
    U_bar: jax.Array,
    K: jax.Array,
    V: jax.Array,
    lo: jax.Array | float = -jnp.inf,
    hi: jax.Array | float = jnp.inf,
) -> tuple[jax.Array, jax.Array]:
    """Run the policy u_t = clip(U_bar_t + V_t + K_t (x_t - X_bar_t), lo, hi) from x0.

    x0 [nx], X_bar [T+1, nx], U_bar, V [T, nu], K [T, nu, nx] -> X [T+1, nx], U [T, nu]
    (U the controls actually applied).
    """

    def body(x, inp):
        xb, ub, Kt, vt = inp
        u = jnp.clip(ub + vt + Kt @ (x - xb), lo, hi)
        return step(x, u), (x, u)

    xT, (Xs, Us) = jax.lax.scan(body, x0, (X_bar[:-1], U_bar, K, V))
    return jnp.concatenate([Xs, xT[None]]), Us


def feedback_rollouts(
    step: StepFn,
    x0: jax.Array,
    X_bar: jax.Array,
    U_bar: jax.Array,
    K: jax.Array,
    V: jax.Array,
    lo: jax.Array | float = -jnp.inf,
    hi: jax.Array | float = jnp.inf,
) -> tuple[jax.Array, jax.Array]:
    """:func:`feedback_rollout` for a batch of offsets V [B, T, nu] around one nominal:
    -> X [B, T+1, nx], U [B, T, nu]. One scan over time of the vmapped step (not a vmap of
    the scan): the same numbers, and the step's program is batched once, not once per pass
    of the scan's batching rule (a shorter trace for MJX steps)."""
    B = V.shape[0]

    def body(x, inp):
        xb, ub, Kt, vt = inp
        u = jnp.clip(ub[None] + vt + (x - xb[None]) @ Kt.T, lo, hi)
        return jax.vmap(step)(x, u), (x, u)

    x0s = jnp.broadcast_to(x0, (B,) + x0.shape)
    xT, (Xs, Us) = jax.lax.scan(body, x0s, (X_bar[:-1], U_bar, K, jnp.swapaxes(V, 0, 1)))
    return jnp.concatenate([Xs, xT[None]]).swapaxes(0, 1), Us.swapaxes(0, 1)


def open_loop(
    step: StepFn, x0: jax.Array, U: jax.Array, lo=-jnp.inf, hi=jnp.inf
) -> tuple[jax.Array, jax.Array]:
    """U [T, nu] clipped to [lo, hi] and applied open loop: -> X [T+1, nx], U [T, nu]."""
    T, nu = U.shape
    zeros_K = jnp.zeros((T, nu, x0.shape[0]), U.dtype)
    X_bar = jnp.zeros((T + 1, x0.shape[0]), x0.dtype)
    return feedback_rollout(step, x0, X_bar, U, zeros_K, jnp.zeros_like(U), lo, hi)
