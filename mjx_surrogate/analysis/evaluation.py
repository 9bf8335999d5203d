"""Evaluation on the black box: replay of controls and policies, cost under process
noise, and the prediction error of any step model on held-out trajectories.

Every rollout here is :func:`mjx_surrogate.trajectory.feedback_rollout` on the system's
own step; the cost is the task's (+inf for a trajectory that is not finite).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from mjx_surrogate.identification import step_models
from mjx_surrogate.identification.data import Dataset, finite_trajectories, u_max
from mjx_surrogate.sharding import vmap_in_chunks
from mjx_surrogate.systems.black_box import BlackBox
from mjx_surrogate.systems.system_jit import system_jit
from mjx_surrogate.tasks import Task, trajectory_cost
from mjx_surrogate.trajectory import feedback_rollout


class Replay(NamedTuple):
    """A policy executed on the black box: costs, trajectories and goal errors, open loop
    (u_t = U_t) and closed loop (u_t = U_t + K_t (x_t - X_t))."""

    cost_open: jax.Array
    cost_closed: jax.Array
    X_open: jax.Array  # [T+1, nx]
    X_closed: jax.Array
    final_error_open: jax.Array  # |x_T - x_goal|
    final_error_closed: jax.Array


@system_jit(static_argnames=("system",))
def replay(system: BlackBox, task: Task, X: jax.Array, U: jax.Array, K: jax.Array) -> Replay:
    """Execute the nominal X [T+1, nx], U [T, nu] with gains K [T, nu, nx] on the black box,
    open and closed loop, controls clipped to the task's limits. The open loop applies U
    alone: a nominal X that is not finite (a surrogate on which iLQR diverged) leaves it
    finite; the closed loop around such a nominal is not."""
    zeros = jnp.zeros_like(U)
    open_loop = (jnp.zeros_like(X), U, jnp.zeros_like(K), zeros)  # u = U + 0 (x - 0)
    Xo, Uo = feedback_rollout(system.step, task.x0, *open_loop, task.u_min, task.u_max)
    Xc, Uc = feedback_rollout(system.step, task.x0, X, U, K, zeros, task.u_min, task.u_max)
    err = lambda Xr: jnp.linalg.norm(Xr[-1] - task.x_goal)  # noqa: E731
    return Replay(trajectory_cost(task, Xo, Uo), trajectory_cost(task, Xc, Uc), Xo, Xc, err(Xo), err(Xc))


@system_jit(static_argnames=("system", "n_trials"))
def evaluate_feedback(
    system: BlackBox,
    task: Task,
    X: jax.Array,
    U: jax.Array,
    K: jax.Array,
    noise_levels: jax.Array,
    key: jax.Array,
    n_trials: int,
):
    """Cost of u_t = U_t + K_t (x_t - X_t) + w_t (closed loop) and U_t + w_t (open loop).

    w_t ~ N(0, (level * U_max)^2) per channel (U_max: :func:`mjx_surrogate.identification.data.u_max`, the
    actuator limit where finite), the same draws for both policies.
    X [T+1, nx], U [T, nu], K [T, nu, nx], noise_levels [L] -> two cost arrays [L, n_trials].
    """
    L = noise_levels.shape[0]
    T, nu = U.shape
    u_scale = u_max(U, task.u_min, task.u_max)  # [nu]
    W = jax.random.normal(key, (L, n_trials, T, nu), U.dtype)
    W = (W * noise_levels[:, None, None, None] * u_scale).reshape(L * n_trials, T, nu)

    # the nominal X is re-simulated in the same program (docstring); only its size is used
    Uc = jnp.clip(U, task.u_min, task.u_max)

    def run(w, gains):
        def body(pair, inp):
            ub, Kt, wt = inp
            u = jnp.clip(ub + wt + Kt @ (pair[1] - pair[0]), task.u_min, task.u_max)
            nxt = jax.vmap(system.step)(pair, jnp.stack([ub, u]))
            return nxt, (pair[1], u)

        pair0 = jnp.stack([task.x0, task.x0])
        last, (Xs, Us) = jax.lax.scan(body, pair0, (Uc, gains, w))
        return trajectory_cost(task, jnp.concatenate([Xs, last[1][None]]), Us)

    per_trial = 4 * (T + 1) * X.shape[-1]  # the pair of trajectories and their step's states
    closed = vmap_in_chunks(lambda w: run(w, K), W, per_trial).reshape(L, n_trials)
    opened = vmap_in_chunks(lambda w: run(w, jnp.zeros_like(K)), W, per_trial).reshape(L, n_trials)
    return closed, opened


GAIN_SCALES = (1.0, 0.5, 0.25, 0.125)  # the feedback's back-off, largest first


class Feedback(NamedTuple):
    """The stored gains under control noise: ``scale`` x K is the feedback to use (0: none
    helps: run open loop); closed [L, n], opened [L, n] the costs of its closed loop and of
    the open loop on the evaluation draws."""

    scale: float
    closed: np.ndarray
    opened: np.ndarray


def levels_made_worse(levels, closed_median, open_median) -> list:
    """The noise levels > 0 at which the closed loop's median cost is not at most the open
    loop's (a NaN counts as worse)."""
    return [lv for lv, c, o in zip(levels, closed_median, open_median) if lv > 0 and not c <= o]


def _helps(levels, closed: np.ndarray, opened: np.ndarray) -> bool:
    """Median closed-loop cost no more than the open loop's at every level > 0."""
    return not levels_made_worse(np.asarray(levels), np.median(closed, axis=1), np.median(opened, axis=1))


def _clearly_helps(levels, closed: np.ndarray, opened: np.ndarray, alpha: float = 0.05) -> bool:
    """:func:`_helps`, and at every level > 0 the closed loop cheaper on more of the paired
    draws than chance explains: a one-sided sign test at ``alpha`` (ties left out, a NaN
    counts against). A bare median chosen on one set of draws overfits them: the
    manipulator's quarter gains helped on the draws they were chosen on and cost +0.7 % on
    the evaluation draws."""
    from scipy.stats import binomtest  # imported here: scipy.stats takes 0.3 s to import

    if not _helps(levels, closed, opened):
        return False
    for lv, c, o in zip(np.asarray(levels), closed, opened):
        if lv <= 0:
            continue
        wins, losses = int(np.sum(c < o)), int(np.sum(~(c < o) & ~(c == o)))
        if wins + losses == 0 or binomtest(wins, wins + losses, 0.5, "greater").pvalue > alpha:
            return False
    return True


def backed_off_feedback(
    system: BlackBox,
    task: Task,
    X: jax.Array,
    U: jax.Array,
    K: jax.Array,
    noise_levels: jax.Array,
    key: jax.Array,
    n_trials: int,
    full: tuple | None = None,
) -> Feedback:
    """The gains K [T, nu, nx] of a solve, backed off until they help under control noise.

    K as it is when its closed loop costs no more than the open loop (median over the draws
    of ``key``, :func:`evaluate_feedback`) at every noise level > 0; otherwise the largest
    scale of :data:`GAIN_SCALES` that does clearly on other draws (``fold_in(key, 1)``;
    :func:`_clearly_helps`), reported on the draws of ``key``, or 0. TVLQR gains are those
    of the linearised problem; under force limits and contacts the full gains can overreact (the Franka's
    servos: +0.7 % with D2C's gains, +2.4 % with the finite-difference oracle's, -0.6 %
    at half). ``full``: K's (closed, opened) on the draws of ``key``, if already evaluated."""
    full = full if full is not None else evaluate_feedback(system, task, X, U, K, noise_levels, key, n_trials)
    closed, opened = (np.asarray(a) for a in full)
    if _helps(noise_levels, closed, opened):
        return Feedback(1.0, closed, opened)
    check = jax.random.fold_in(key, 1)
    for scale in GAIN_SCALES[1:]:
        c, o = (
            np.asarray(a)
            for a in evaluate_feedback(system, task, X, U, scale * K, noise_levels, check, n_trials)
        )
        if _clearly_helps(noise_levels, c, o):
            closed = np.asarray(
                evaluate_feedback(system, task, X, U, scale * K, noise_levels, key, n_trials)[0]
            )
            return Feedback(scale, closed, opened)
    return Feedback(0.0, opened, opened)


@jax.jit
def _predictions(step_t: jax.tree_util.Partial, X: jax.Array, U: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Open-loop predictions from X[:, 0] [B, T+1, nx] and one-step predictions [B, T, nx]."""
    return step_models.predict(step_t, X[:, 0], U), step_models.one_step(step_t, X, U)


def prediction_errors(step_t: step_models.StepT, test: Dataset) -> tuple[dict, np.ndarray]:
    """One-step and open-loop multi-step RMSE of ``step_t`` on test trajectories (pass
    fitted models through :func:`step_models.as_pytree` to compile once per structure).

    Returns (metrics, X_pred [N, T+1, nx]). metrics: one_step_rmse and multi_step_rmse
    over all test transitions/steps, multi_step_median (median over trajectories of each
    trajectory's RMSE) and diverged (fraction of trajectories whose prediction went
    non-finite). RMSEs that are not finite are reported as None.
    """
    X, U = finite_trajectories(test)
    if not isinstance(step_t, jax.tree_util.Partial):
        step_t = jax.tree_util.Partial(step_t)
    pred, one = _predictions(step_t, X, U)
    err_multi = (np.asarray(pred) - X) ** 2
    per_traj = np.sqrt(err_multi.reshape(err_multi.shape[0], -1).mean(1))
    finite = np.isfinite(per_traj)
    out = {
        "one_step_rmse": finite_or_none(step_models.rmse(one, X[:, 1:])),
        "multi_step_rmse": finite_or_none(np.sqrt(err_multi.mean())) if finite.all() else None,
        "multi_step_median": finite_or_none(np.median(np.where(finite, per_traj, np.inf))),
        "diverged": float(1.0 - finite.mean()),
    }
    return out, np.asarray(pred)


def error_grows(lo: float | None, hi: float | None) -> bool:
    """A prediction error grows from the lowest to the highest level: it is larger there,
    or it diverges (None) there, from a finite value at the lowest level."""
    return lo is not None and (hi is None or hi > lo)


def finite_or_none(v) -> float | None:
    """A float for JSON, None where it is not finite (or is None)."""
    if v is None:
        return None
    v = float(v)
    return v if np.isfinite(v) else None
