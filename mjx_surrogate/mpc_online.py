"""SINDy-MPC refitted online: the SINDy-MPC paper's low-data setting (Kaiser, Kutz, Brunton
2018), in which the model keeps learning from the episode it controls.

Notation as :mod:`mjx_surrogate.mpc`. At control step n the model's coefficients C [P, nx]
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
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp

from mjx_surrogate import sysid as sid
from mjx_surrogate.data import Transitions
from mjx_surrogate.ilqr import ILQRParams, Problem
from mjx_surrogate.linalg import spd_solve
from mjx_surrogate.mpc import MPCResult, first_plan, ilqr_replan, shifted
from mjx_surrogate.surrogates.sindy import SindyModel, design
from mjx_surrogate.systems.system import System
from mjx_surrogate.tasks import Task, task_cost, trajectory_cost

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


@functools.partial(jax.jit, static_argnames=("plant", "steps"))
def refitted_sindy_mpc(
    model: SindyModel,
    offline: Transitions,
    plant: System,
    task: Task,
    U0: jax.Array,
    key: jax.Array,
    steps: int,
    params: ILQRParams = ILQRParams(max_iter=5),
    process_noise: float | jax.Array = 0.0,
    weight: float | jax.Array = 10.0,
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
    nx, nu = x0.shape[0], U0.shape[-1]

    def control_step(carry, inputs):
        x, plan, Xb, Ub, Yb = carry
        n, k = inputs
        k_plan, k_noise = jax.random.split(k)
        w = weight * (jnp.arange(steps) < n).astype(x.dtype)
        m = refit(model, gram0, proj0, scale, design(model.spec, Xb, Ub), _targets(model, Xb, Yb), w)
        prob = Problem(
            m.step,
            lambda X, U_, K, kk: sid.exact_jacobians(m.step, X, U_),
            task_cost(task),
            x,
            task.u_min,
            task.u_max,
        )
        plan, (cost, its, ident) = ilqr_replan(prob, plan, params, k_plan)
        u = plan.U[0]
        x_next = plant.step(x, u) + process_noise * jax.random.normal(k_noise, x.shape, x.dtype)
        Xb, Ub, Yb = Xb.at[n].set(x), Ub.at[n].set(u), Yb.at[n].set(x_next)
        return (x_next, shifted(plan), Xb, Ub, Yb), (x, u, cost, its, ident)

    empty = (
        jnp.zeros((steps, nx), x0.dtype),
        jnp.zeros((steps, nu), x0.dtype),
        jnp.zeros((steps, nx), x0.dtype),
    )
    (xN, *_), (X, U, plan_cost, its, ident) = jax.lax.scan(
        control_step,
        (x0, first_plan(U0, x0), *empty),
        (jnp.arange(steps), jax.random.split(key, steps)),
    )
    X = jnp.concatenate([X, xN[None]])
    return MPCResult(X, U, trajectory_cost(task, X, U), plan_cost, its, ident)
