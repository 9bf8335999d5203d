"""The receding-horizon loop every planner shares (:func:`episode`) and the plan it carries
from one replan to the next (:class:`Plan`): replan from the measured state, step the plant
under the plan until the next replan, shift the plan, repeat; one program per episode.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from mjx_surrogate.progress import NO_PROGRESS, ProgressMeter, poll_step

POLLS_PER_EPISODE = 25  # progress reports (and stop checks) per episode, at most about


class Plan(NamedTuple):
    """A replan's result and the next one's warm start: controls U [H, nu] and the policy
    around them, u = U + K (x - X), with X [H+1, nx] and gains K [H, nu, nx] (K = 0: the
    controls alone)."""

    U: jax.Array
    X: jax.Array
    K: jax.Array


def first_plan(U0: jax.Array, x0: jax.Array) -> Plan:
    """The warm start of an episode's first replan: U0 [H, nu], no feedback."""
    H, nu = U0.shape
    return Plan(
        U0.astype(x0.dtype),
        jnp.zeros((H + 1, x0.shape[0]), x0.dtype),
        jnp.zeros((H, nu, x0.shape[0]), x0.dtype),
    )


def shifted(plan, steps: int = 1):
    """Every leaf of a plan [H, ...] moved ``steps`` control steps on, its last row repeated."""
    return jax.tree.map(lambda a: jnp.concatenate([a[steps:], jnp.repeat(a[-1:], steps, axis=0)]), plan)


def bound_episode(fn, *args, **fixed):
    """A planner's episode, ``episode(*, plant, key, process_noise, progress)``: the
    episode function ``fn`` (e.g. ``receding_horizon``) with its positional ``args`` and
    settings ``fixed`` bound, what each episode brings passed by name."""

    def one(*, plant, key, process_noise, progress):
        return fn(*args, plant=plant, key=key, process_noise=process_noise, progress=progress, **fixed)

    return one


def episode(
    replan,
    *,
    plant_step,
    x0: jax.Array,
    plan0,
    key: jax.Array,
    steps: int,
    process_noise: float | jax.Array = 0.0,
    memory=None,
    observe=None,
    progress: ProgressMeter = NO_PROGRESS,
    replan_every: int = 1,
    limits: tuple | None = None,
    shift=None,
):
    """The receding-horizon loop every planner shares (every argument but ``replan``
    keyword-only): ``replan(x, plan, key, n) -> (plan, info)`` at control step n from the
    measured x and the previous plan shifted by
    ``replan_every`` = r steps (``plan0``: the first one's warm start; a :class:`Plan` or U
    [H, nu], leaves with the control steps leading), every r control steps; in between the
    plant steps at its own rate under the plan: u_{n+j} = U[j] + K[j] (x_{n+j} - X[j]) for a
    :class:`Plan` (its feedback gains, clipped to ``limits`` (lo, hi) when given), U[j] for
    controls alone (U [H, nu], or any plan with a ``U`` field), then the process noise is
    added. ``shift(plan, r) -> plan``: how a plan moves on r steps (default
    :func:`shifted`). r = 1 applies each plan's first
    control only. A controller that learns during the episode passes ``memory`` (a pytree)
    and ``observe(memory, n, x, u, x_next) -> memory``, called after every plant step; its
    replan is then ``replan(x, plan, key, n, memory) -> (plan, info, memory)``.
    ``progress``: told of every k-th replan (k = replans // POLLS_PER_EPISODE, at least 1:
    each report is a host callback, docs/performance.md); once it reports a stop request,
    the remaining steps are skipped (their rows of X, U and info are NaN, or 0 for
    integers). Control step n draws its noise, and a replan at n its key, from the n-th of
    ``steps`` keys split from ``key``, whatever r.
    -> X [steps+1, nx], U [steps, nu], info stacked [steps / r, ...]."""
    r = replan_every
    if r < 1 or steps % r:
        raise ValueError(f"replan_every: a divisor of the {steps} steps, got {r}")

    shift = shifted if shift is None else shift

    def controls(plan):
        return plan.U if hasattr(plan, "U") else plan

    def act(plan, j, x):
        if not hasattr(plan, "K"):  # controls alone: no policy around them
            return controls(plan)[j]
        u = plan.U[j] + plan.K[j] @ (x - plan.X[j])
        return u if limits is None else jnp.clip(u, *limits)

    def plant(plan, n, carry, inputs):
        x, mem = carry
        j, k = inputs
        u = controls(plan)[0] if r == 1 else act(plan, j, x)
        k_noise = jax.random.split(k)[1]
        x_next = plant_step(x, u) + process_noise * jax.random.normal(k_noise, x.shape, x.dtype)
        if observe is not None:
            mem = observe(mem, n + j, x, u, x_next)
        return (x_next, mem), (x, u)

    @jax.jit  # traced once: for the skipped branch's shapes and for the block itself
    def advance(x, plan, mem, n, keys):
        k_plan = jax.random.split(keys[0])[0]
        if observe is None:
            plan, info = replan(x, plan, k_plan, n)
        else:
            plan, info, mem = replan(x, plan, k_plan, n, mem)
        if r == 1:
            (x, mem), (xs, us) = plant(plan, n, (x, mem), (0, keys[0]))
            xs, us = xs[None], us[None]
        else:
            (x, mem), (xs, us) = jax.lax.scan(
                lambda c, i: plant(plan, n, c, i), (x, mem), (jnp.arange(r), keys)
            )
        return (x, shift(plan, r), mem), (xs, us, info)

    def block(carry, inputs):
        x, plan, mem, stopped = carry
        i, keys = inputs
        n = i * r
        # unbatched (one answer for a vmapped batch), so both conds really branch
        quiet = stopped | (i % every != 0)
        stopped = jax.lax.cond(quiet, lambda: stopped, lambda: poll_step(progress, n))
        shapes = jax.eval_shape(advance, x, plan, mem, n, keys)[1]

        def skip():
            return (x, plan, mem), jax.tree.map(_blank, shapes)

        (x, plan, mem), row = jax.lax.cond(stopped, skip, lambda: advance(x, plan, mem, n, keys))
        return (x, plan, mem, stopped), row

    replans = steps // r
    every = max(1, replans // POLLS_PER_EPISODE)
    plan0 = jax.tree.map(lambda a: a.astype(x0.dtype), plan0)
    keys = jax.random.split(key, steps)
    keys = keys.reshape((replans, r) + keys.shape[1:])
    carry = (x0, plan0, memory, jnp.array(False))
    (xN, _, _, stopped), (X, U, info) = jax.lax.scan(block, carry, (jnp.arange(replans), keys))
    X, U = X.reshape((steps,) + X.shape[2:]), U.reshape((steps,) + U.shape[2:])
    return jnp.concatenate([X, jnp.where(stopped, jnp.nan, xN)[None]]), U, info


def _blank(s: jax.ShapeDtypeStruct) -> jax.Array:
    """A skipped step's row: NaN, or 0 for integers and booleans."""
    fill = jnp.nan if jnp.issubdtype(s.dtype, jnp.inexact) else 0
    return jnp.full(s.shape, fill, s.dtype)
