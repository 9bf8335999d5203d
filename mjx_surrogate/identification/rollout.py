"""Batched rollouts of a system, plain and perturbed around a nominal (x0, U).

The batch axis leads every array and is spread over ``system.mesh`` when the system has
one (:mod:`mjx_surrogate.sharding`).
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import jax

from mjx_surrogate import sharding
from mjx_surrogate.systems.black_box import BlackBox


@functools.partial(jax.jit, static_argnums=0)
def rollout(system: BlackBox, x0: jax.Array, U: jax.Array) -> jax.Array:
    """x0 [B, nx], U [B, T, nu] -> X [B, T+1, nx] on the system's backend."""
    return sharding.map_batch(system.rollout, system.mesh, x0, U)


class PerturbedRollouts(NamedTuple):
    """dx0 [R, nx], dU [R, T, nu] drawn perturbations; X [R, T+1, nx] the trajectories
    from x0 + dx0 under U + dU."""

    dx0: jax.Array
    dU: jax.Array
    X: jax.Array


def draw_perturbations(
    key: jax.Array, n: int, x0: jax.Array, U: jax.Array, sigma_x: float, sigma_u: float
) -> tuple[jax.Array, jax.Array]:
    """Gaussian perturbations dx0 ~ N(0, sigma_x^2) [n, nx], dU ~ N(0, sigma_u^2) [n, T, nu]."""
    kx, ku = jax.random.split(key)
    dx0 = sigma_x * jax.random.normal(kx, (n,) + x0.shape, x0.dtype)
    dU = sigma_u * jax.random.normal(ku, (n,) + U.shape, U.dtype)
    return dx0, dU


def perturbed_rollouts_fn(
    system: BlackBox, key: jax.Array, x0: jax.Array, U: jax.Array, n: int, sigma_x: float, sigma_u: float
) -> PerturbedRollouts:
    """Unjitted body of :func:`perturbed_rollouts`, for use inside larger traces."""
    dx0, dU = draw_perturbations(key, n, x0, U, sigma_x, sigma_u)
    X = sharding.map_batch(system.rollout, system.mesh, x0[None] + dx0, U[None] + dU)
    return PerturbedRollouts(dx0, dU, X)


@functools.partial(jax.jit, static_argnums=(0, 4))
def perturbed_rollouts(
    system: BlackBox,
    key: jax.Array,
    x0: jax.Array,
    U: jax.Array,
    n: int,
    sigma_x: float | jax.Array,
    sigma_u: float | jax.Array,
) -> PerturbedRollouts:
    """R = n rollouts from x0 [nx] + dx0 under U [T, nu] + dU, one jitted batched call."""
    return perturbed_rollouts_fn(system, key, x0, U, n, sigma_x, sigma_u)
