"""Open-loop simulation of any one-step map, the shared core of every rollout.

A step function maps ``(x[nx], u[nu]) -> x_next[nx]``; it may be a MuJoCo backend,
an LTV model or a surrogate. Batches lead: ``[B, ...]``.
"""

from __future__ import annotations

from typing import Callable

import jax
import jax.numpy as jnp

StepFn = Callable[[jax.Array, jax.Array], jax.Array]


def simulate(step: StepFn, x0: jax.Array, U: jax.Array) -> jax.Array:
    """Roll one trajectory: x0 [nx], U [T, nu] -> X [T+1, nx] by ``lax.scan``."""

    def body(x, u):
        x_next = step(x, u)
        return x_next, x_next

    _, xs = jax.lax.scan(body, x0, U)
    return jnp.concatenate([x0[None], xs], axis=0)


def simulate_batch(step: StepFn, x0: jax.Array, U: jax.Array) -> jax.Array:
    """x0 [B, nx], U [B, T, nu] -> X [B, T+1, nx] (vmap of :func:`simulate`)."""
    return jax.vmap(simulate, in_axes=(None, 0, 0))(step, x0, U)
