"""Derivative-free receding-horizon control on the black box: predictive sampling and MPPI.

The same episode as :func:`mjx_surrogate.control.mpc.receding_horizon` (notation there), with a
sampling planner instead of iLQR. At control step n, from the measured x_n and the
shifted previous plan U (H steps):

    U_i = clip(U + sigma * eps_i),  eps_i ~ N(0, I),  i = 1 .. S-1;   U_0 = U (kept)
    J_i = J(rollout of U_i from x_n on the black box)

Predictive sampling (``temperature`` None) keeps argmin_i J_i; MPPI weights the samples by
w_i = exp(-(J_i - min J) / temperature) / sum and plans sum_i w_i U_i. A replan simulates
S H black-box control steps (MPPI one more rollout, H steps, to cost its mean plan).

Smooth samples (``knots`` k >= 1, as hydrax's spline-parametrised planners): eps_i is drawn at
k knots spread evenly over the horizon (its first and last step) and interpolated linearly
in between, eps_i = W z_i with W [H, k] and z_i ~ N(0, I) [k, nu]: a perturbation varies
slowly over the horizon instead of independently at every step. k = H is the default's
draws exactly (W = I); k = 1 perturbs every step by the same amount.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from mjx_surrogate.control.episode import episode
from mjx_surrogate.control.mpc import MPCResult
from mjx_surrogate.progress import NO_PROGRESS, ProgressMeter
from mjx_surrogate.systems.system import System
from mjx_surrogate.tasks import Task, at_step, trajectory_cost
from mjx_surrogate.trajectory import open_loop


def interpolation(H: int, knots: int) -> np.ndarray:
    """W [H, knots]: linear interpolation from values at ``knots`` times spread evenly over
    control steps 0 .. H-1 (both ends included; one knot: a constant) to every step."""
    t, tau = np.arange(H, dtype=float), np.linspace(0.0, H - 1.0, knots)
    if knots == 1:
        return np.ones((H, 1))
    return np.stack([np.interp(t, tau, e) for e in np.eye(knots)], axis=1)


def perturbations(key: jax.Array, n: int, H: int, nu: int, knots: int, dtype) -> jax.Array:
    """eps [n, H, nu] ~ N(0, I) at every step (knots 0), or drawn at ``knots`` knots and
    interpolated linearly between them (module docstring)."""
    if knots == 0:
        return jax.random.normal(key, (n, H, nu), dtype)
    W = jnp.asarray(interpolation(H, knots), dtype)
    return jnp.einsum("tk,skj->stj", W, jax.random.normal(key, (n, knots, nu), dtype))


@functools.partial(
    jax.jit, static_argnames=("system", "steps", "n_samples", "plant", "knots", "replan_every")
)
def sampling_mpc(
    system: System,
    task: Task,
    U0: jax.Array,
    key: jax.Array,
    steps: int,
    sigma: float | jax.Array,
    n_samples: int = 64,
    temperature: float | jax.Array | None = None,
    process_noise: float | jax.Array = 0.0,
    plant: System | None = None,
    knots: int = 0,
    progress: ProgressMeter = NO_PROGRESS,
    replan_every: int = 1,
) -> MPCResult:
    """One episode of ``steps`` control steps from ``task.x0`` (horizon H = task.T), the
    first plan U0 [H, nu]; ``sigma`` (scalar or [nu], control units) scales the samples,
    drawn at every step (``knots`` 0) or at that many knots (module docstring)."""
    lo, hi = task.u_min, task.u_max
    plant_step = (plant if plant is not None else system).step

    def plan_cost(x, U, n):
        X, Uc = open_loop(system.step, x, U, lo, hi)
        return trajectory_cost(at_step(task, n), X, Uc)

    def replan(x, U, k, n):
        eps = perturbations(k, n_samples - 1, *U.shape, knots, U.dtype)
        samples = jnp.concatenate([U[None], jnp.clip(U + sigma * eps, lo, hi)])  # [S, H, nu]
        J = jax.vmap(lambda Ui: plan_cost(x, Ui, n))(samples)
        if temperature is None:
            best = jnp.argmin(J)
            return samples[best], J[best]
        w = jax.nn.softmax(-(J - jnp.min(J)) / temperature)
        mean = jnp.einsum("s,stu->tu", w, samples)
        return mean, plan_cost(x, mean, n)

    X, U, J = episode(
        replan,
        plant_step,
        task.x0,
        U0,
        key,
        steps,
        process_noise,
        progress=progress,
        replan_every=replan_every,
    )
    ones = jnp.ones(J.shape, jnp.int32)
    return MPCResult(X, U, trajectory_cost(task, X, U), J, ones, jnp.zeros(J.shape + (1,), jnp.int8))


def black_box_steps(n_samples: int, horizon: int, mppi: bool) -> int:
    """Black-box control steps one replan simulates (not counting the plant's own steps)."""
    return (n_samples + int(mppi)) * horizon
