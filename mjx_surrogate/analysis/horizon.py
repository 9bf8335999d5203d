"""Identification error against the horizon: open-loop against closed-loop rollouts.

The paper identifies its LTV models from rollouts of the whole horizon under perturbed
open-loop controls (sysid scheme "rollout"). Around an unstable optimum the perturbations
grow along the horizon, so the data at step t leave the region where the linearisation
holds, and the error of (A_t, B_t) grows with t. Rolled out under the optimum's feedback
gains K (u_t = U_t + dU_t + K_t (x_t - X_t), scheme "closed_loop"), the perturbations stay
bounded; Pfrommer et al. (ICML 2023) prove that stabilising gains remove the exponential
dependence of the identification error on the horizon. This module measures both.

Notation: nominal X [T+1, nx], U [T, nu], gains K [T, nu, nx]; n rollouts; dx0 [n, nx] the
start offsets, dU [n, T, nu] the control noise; the reference Jacobians A_ref [T, nx, nx],
B_ref [T, nx, nu] (exact or finite-difference, see :func:`mjx_surrogate.control.d2c.exact_linearize`).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from mjx_surrogate import sharding
from mjx_surrogate.identification import sysid
from mjx_surrogate.linalg import ltv_relative_error, relative_frobenius
from mjx_surrogate.systems.system_jit import system_jit
from mjx_surrogate.trajectory import feedback_rollout


class HorizonErrors(NamedTuple):
    """Per time step t (the data at t come from rollouts t steps long)."""

    error: jax.Array  # [2, T] relative Frobenius error of [A_t B_t]: open loop, closed loop
    closed_loop_error: jax.Array  # [2, T] relative error of A_t + B_t K_t (the loop the gains close)
    spread: jax.Array  # [2, T+1] median over rollouts of ||x_t - X_t|| / RMS ||X||


@system_jit(static_argnames=("system", "n"))
def identification_errors(
    system,
    X: jax.Array,
    U: jax.Array,
    K: jax.Array,
    A_ref: jax.Array,
    B_ref: jax.Array,
    key: jax.Array,
    n: int,
    sigma_x0: jax.Array,
    sigma_u: jax.Array,
    u_min: jax.Array,
    u_max: jax.Array,
) -> HorizonErrors:
    """n rollouts from X[0] + dx0 (dx0 ~ N(0, diag(sigma_x0^2)), sigma_x0 [nx]) under
    U + dU (dU ~ N(0, diag(sigma_u^2)), sigma_u [nu]), once open loop and once under K; the
    same draws for both. Each is regressed per t on the applied controls
    (:func:`mjx_surrogate.identification.sysid.fit_from_trajectories`); controls are clipped to the limits."""
    kx, ku = jax.random.split(key)
    dx0 = sigma_x0 * jax.random.normal(kx, (n,) + X[0].shape, X.dtype)
    dU = sigma_u * jax.random.normal(ku, (n,) + U.shape, U.dtype)
    scale = jnp.sqrt(jnp.mean(jnp.sum(X**2, -1)))

    def one(gains):
        def roll(d0, dv, X, U, gains):
            run = lambda a, b: feedback_rollout(system.step, X[0] + a, X, U, gains, b, u_min, u_max)  # noqa: E731
            return jax.vmap(run)(d0, dv)

        Xp, Up = sharding.map_batch(roll, system.mesh, dx0, dU, rest=(X, U, gains))
        A, B = sysid.fit_from_trajectories(Xp - X[None], Up - U[None])
        spread = jnp.nanmedian(jnp.linalg.norm(Xp - X[None], axis=-1), axis=0) / scale
        e_cl = relative_frobenius(A + B @ K, A_ref + B_ref @ K)
        return ltv_relative_error(A, B, A_ref, B_ref), e_cl, spread

    o, c = one(jnp.zeros_like(K)), one(K)
    return HorizonErrors(*(jnp.stack([a, b]) for a, b in zip(o, c)))
