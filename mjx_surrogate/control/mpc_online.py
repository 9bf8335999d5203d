"""Surrogate MPC refitted online: the SINDy-MPC paper's low-data setting (Kaiser, Kutz,
Brunton 2018), in which the model keeps learning from the episode it controls.

Notation as :mod:`mjx_surrogate.control.mpc`. At control step n the model's coefficients C [P, nx]
are refitted by least squares on the R offline transitions it was first fitted on and on
the episode's own n transitions (x_m, u_m, x_{m+1}), m < n, each of which weighs
``weight`` offline ones:

    (Theta_0' Theta_0 + weight Theta_n' Theta_n) C = Theta_0' Y_0 + weight Theta_n' Y_n

with the columns of Theta scaled by their offline norms, each target restricted to the
support of the first fit (a thresholded coefficient stays zero). Then iLQR plans on the
refitted model, Jacobians by ``jax.jacfwd`` through it, as :func:`mpc.surrogate_mpc`. On a
plant that differs from the model the data came from, the episode's transitions pull the
model towards the plant. Shapes stay static: the episode's transitions live in a buffer
of N rows whose unfilled rows weigh zero.

An MLP has no closed-form refit: before every replan it takes ``updates`` steps of its own
optimiser (``surrogate.mlp``: Adam, learning rate, weight decay) on the weighted loss

    L(p) = (sum_{i in batch} |r_i(p)|^2 + weight sum_{m < n} |r_m(p)|^2) / (nx (b + weight n))

of its standardised residuals r, a fresh minibatch of b offline transitions per step
(drawn with replacement) and the episode's n transitions; its parameters and optimiser
state carry over from replan to replan. With ``updates = 0`` it is the plain MLP-MPC.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import optax
from flax import nnx

from mjx_surrogate.control.episode import episode, first_plan
from mjx_surrogate.control.ilqr import ILQRParams
from mjx_surrogate.control.mpc import MPCResult, surrogate_replan
from mjx_surrogate.identification.data import Transitions
from mjx_surrogate.linalg import spd_solve
from mjx_surrogate.progress import NO_PROGRESS, ProgressMeter
from mjx_surrogate.surrogates.mlp import MLPModel, MLPSpec, optimizer, targets
from mjx_surrogate.surrogates.sindy import SindyModel, design
from mjx_surrogate.systems.black_box import BlackBox
from mjx_surrogate.tasks import Task, at_step, trajectory_cost

RIDGE = 1e-10  # relative to the scaled Gram's unit diagonal: keeps an empty support solvable


def _targets(model: SindyModel, x: jax.Array, x_next: jax.Array) -> jax.Array:
    return x_next - x if model.increment else x_next


def refit(model: SindyModel, gram0, proj0, scale, theta_on, y_on, w) -> SindyModel:
    """The model refitted on the offline normal equations (gram0 [P, P], proj0 [P, nx] of
    the scaled columns) plus the weighted rows theta_on [M, P], y_on [M, nx], w [M]."""
    ts = theta_on / scale
    g = gram0 + (ts * w[:, None]).T @ ts
    b = proj0 + (ts * w[:, None]).T @ y_on
    support = (model.coef != 0).astype(g.dtype)  # [P, nx]

    def one_target(b_k, m):
        a = g * m[:, None] * m[None, :] + jnp.diag(RIDGE * m + (1.0 - m))
        c, _ = spd_solve(a, (b_k * m)[:, None])
        return c[:, 0] * m

    coef = jax.vmap(one_target, in_axes=(1, 1), out_axes=1)(b, support)
    return model.replace(coef=coef / scale[:, None])


@functools.partial(jax.jit, static_argnames=("plant", "steps", "replan_every"))
def refitted_sindy_mpc(
    model: SindyModel,
    offline: Transitions,
    task: Task,
    U0: jax.Array,
    *,
    plant: BlackBox,
    key: jax.Array,
    steps: int,
    params: ILQRParams = ILQRParams(max_iter=5),
    process_noise: float | jax.Array = 0.0,
    weight: float | jax.Array = 10.0,
    progress: ProgressMeter = NO_PROGRESS,
    replan_every: int = 1,
) -> MPCResult:
    """One episode of ``steps`` control steps on ``plant`` from ``task.x0``: SINDy-MPC whose
    model is refitted before every replan (module docstring). ``offline``: the transitions
    the model was fitted on; U0 [H, nu]; no black-box call but the plant's steps."""
    x0 = task.x0
    theta0 = design(model.spec, offline.x.astype(x0.dtype), offline.u.astype(x0.dtype))
    scale = jnp.linalg.norm(theta0, axis=0)
    scale = jnp.where(scale > 0, scale, 1.0)
    ts0 = theta0 / scale
    gram0 = ts0.T @ ts0
    proj0 = ts0.T @ _targets(model, offline.x, offline.x_next).astype(x0.dtype)

    def replan(x, plan, key, n, seen: Transitions):
        w = weight * (jnp.arange(steps) < n).astype(x.dtype)
        m = refit(
            model,
            gram0,
            proj0,
            scale,
            design(model.spec, seen.x, seen.u),
            _targets(model, seen.x, seen.x_next),
            w,
        )
        plan, info = surrogate_replan(m, at_step(task, n), x, plan, params, key)
        return plan, info, seen

    X, U, (plan_cost, its, ident) = episode(
        replan,
        plant_step=plant.step,
        x0=x0,
        plan0=first_plan(U0, x0),
        key=key,
        steps=steps,
        process_noise=process_noise,
        memory=empty_transitions(steps, x0.shape[0], U0.shape[-1], x0.dtype),
        observe=record,
        progress=progress,
        replan_every=replan_every,
        limits=(task.u_min, task.u_max),
    )
    return MPCResult(X, U, trajectory_cost(task, X, U), plan_cost, its, ident)


def empty_transitions(steps: int, nx: int, nu: int, dtype) -> Transitions:
    """A buffer for an episode's transitions: x [steps, nx], u [steps, nu], x_next [steps, nx]."""
    return Transitions(
        jnp.zeros((steps, nx), dtype), jnp.zeros((steps, nu), dtype), jnp.zeros((steps, nx), dtype)
    )


def record(seen: Transitions, n, x, u, x_next) -> Transitions:
    """``seen`` with the episode's n-th transition written to row n."""
    return Transitions(seen.x.at[n].set(x), seen.u.at[n].set(u), seen.x_next.at[n].set(x_next))


def weighted_loss(model: MLPModel, p, z_off, y_off, z_on, y_on, w) -> jax.Array:
    """The loss above at parameters p: offline rows z_off [b, nz], y_off [b, nx] of weight 1,
    the episode's rows z_on [N, nz], y_on [N, nx] of weights w [N] (physical units)."""
    norm = model.norm

    def sq(z, y):  # [rows] squared standardised residuals, summed over the state
        zs = ((z - norm.z_mean) / norm.z_std).astype(jnp.float32)
        ys = ((y - norm.y_mean) / norm.y_std).astype(jnp.float32)
        return jnp.sum((nnx.merge(model.graphdef, p)(zs) - ys) ** 2, axis=-1)

    w = w.astype(jnp.float32)
    total = jnp.sum(sq(z_off, y_off)) + jnp.sum(w * sq(z_on, y_on))
    return total / (y_off.shape[-1] * (z_off.shape[0] + jnp.sum(w)))


@functools.partial(jax.jit, static_argnames=("plant", "steps", "spec", "updates", "replan_every"))
def refitted_mlp_mpc(
    model: MLPModel,
    offline: Transitions,
    task: Task,
    U0: jax.Array,
    *,
    plant: BlackBox,
    key: jax.Array,
    steps: int,
    spec: MLPSpec,
    updates: int,
    params: ILQRParams = ILQRParams(max_iter=5),
    process_noise: float | jax.Array = 0.0,
    weight: float | jax.Array = 10.0,
    progress: ProgressMeter = NO_PROGRESS,
    replan_every: int = 1,
) -> MPCResult:
    """One episode of ``steps`` control steps on ``plant`` from ``task.x0``: MLP-MPC whose
    network takes ``updates`` optimiser steps (``spec``'s) before every replan (module
    docstring). ``offline``: the transitions it was trained on; U0 [H, nu]."""
    x0 = task.x0
    z_off = jnp.concatenate([offline.x, offline.u], -1)
    y_off = targets(offline.x, offline.x_next, model.increment)
    b = min(spec.batch_size, z_off.shape[0])
    opt = optimizer(spec)

    def replan(x, plan, key, n, memory):
        seen, p, state = memory
        k_batch, k_plan = jax.random.split(key)
        w = weight * (jnp.arange(steps) < n)
        z_on = jnp.concatenate([seen.x, seen.u], -1)
        y_on = targets(seen.x, seen.x_next, model.increment)

        def update(carry, k):
            p, state = carry
            i = jax.random.randint(k, (b,), 0, z_off.shape[0])  # with replacement: no sort
            g = jax.grad(lambda q: weighted_loss(model, q, z_off[i], y_off[i], z_on, y_on, w))(p)
            upd, state = opt.update(g, state, p)
            return (optax.apply_updates(p, upd), state), None

        (p, state), _ = jax.lax.scan(update, (p, state), jax.random.split(k_batch, updates))
        m = model.replace(params=p)
        plan, info = surrogate_replan(m, at_step(task, n), x, plan, params, k_plan)
        return plan, info, (seen, p, state)

    memory = (
        empty_transitions(steps, x0.shape[0], U0.shape[-1], x0.dtype),
        model.params,
        opt.init(model.params),
    )
    X, U, (plan_cost, its, ident) = episode(
        replan,
        plant_step=plant.step,
        x0=x0,
        plan0=first_plan(U0, x0),
        key=key,
        steps=steps,
        process_noise=process_noise,
        memory=memory,
        observe=lambda mem, n, x, u, x_next: (record(mem[0], n, x, u, x_next), *mem[1:]),
        progress=progress,
        replan_every=replan_every,
        limits=(task.u_min, task.u_max),
    )
    return MPCResult(X, U, trajectory_cost(task, X, U), plan_cost, its, ident)
