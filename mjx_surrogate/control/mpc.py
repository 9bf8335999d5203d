"""Receding-horizon control (MPC) on a black box: replan from the measured state, apply the
first control, repeat.

Notation: an episode of N control steps on the plant; at step n the controller solves the
horizon-H problem ``task`` (``task.T`` = H) from the measured x_n, warm-started from its
previous plan shifted by one step (its last row repeated; :func:`warm_start`: rolled out
through the plan's gains or with its controls alone, whichever costs less), with at most
``params.max_iter`` iLQR iterations, and applies u_n = U_plan[0]:

    x_{n+1} = f_plant(x_n, u_n) + w_n,    w_n ~ N(0, process_noise^2 I)

(process noise in state units, drawn from the episode's key). The plant defaults to the
controller's system; a different plant (other masses, another parameter) is the model
mismatch the controller does not know. A task with a ``deadline`` D (a finite-time task,
its goal a terminal cost) is planned at step n as :func:`~mjx_surrogate.tasks.at_step` has
it: the plan ends at the task's end, stage min(D - n, H), so that the goal stays where the
task put it instead of receding with the horizon.
Controllers: "d2c" (LTV models identified on the black box at every replan), "jacfwd" and
"finite_difference" (the exact-Jacobian oracles); :func:`surrogate_mpc` plans on a global
surrogate instead (SINDy-MPC, MLP-MPC) and :func:`tracking` replays a fixed nominal with its
TVLQR gains (no replanning). D2C-MPC with ``sysid.every`` = k identifies at every k-th
step of the horizon only, interpolating between (MuJoCo MPC's derivative skip). The
episode is one program: a ``lax.scan`` over the control steps, each replan an iLQR
``while_loop``; episodes batch with ``jax.vmap`` over x0 and keys.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from mjx_surrogate.control.d2c import problem
from mjx_surrogate.control.effort import simulation_curve, steps_per_identification
from mjx_surrogate.control.episode import Plan, episode, first_plan
from mjx_surrogate.control.ilqr import ILQRParams, Problem, ilqr_advance, ilqr_init, ilqr_result
from mjx_surrogate.identification import sysid as sid
from mjx_surrogate.progress import NO_PROGRESS, ProgressMeter
from mjx_surrogate.systems.black_box import BlackBox
from mjx_surrogate.tasks import Task, at_step, task_cost, trajectory_cost

CONTROLLERS = ("d2c", "jacfwd", "finite_difference")


class MPCResult(NamedTuple):
    """X [N+1, nx], U [N, nu]: the closed loop on the plant; cost: the task's cost of (X, U)
    over the N steps (terminal term at x_N); plan_cost [R]: each of the R replans' (one
    every N / R control steps) predicted horizon cost; iterations [R] and identified [R,
    max_iter]: each replan's iLQR iterations and
    identifications (as :class:`~mjx_surrogate.control.ilqr.ILQRResult`)."""

    X: jax.Array
    U: jax.Array
    cost: jax.Array
    plan_cost: jax.Array
    iterations: jax.Array
    identified: jax.Array


@functools.partial(jax.jit, static_argnames=("system", "steps", "controller", "plant", "replan_every"))
def receding_horizon(
    system: BlackBox,
    task: Task,
    U0: jax.Array,
    *,
    key: jax.Array,
    steps: int,
    params: ILQRParams = ILQRParams(max_iter=5),
    sysid: sid.SysIdParams = sid.SysIdParams(),
    process_noise: float | jax.Array = 0.0,
    controller: str = "d2c",
    plant: BlackBox | None = None,
    progress: ProgressMeter = NO_PROGRESS,
    replan_every: int = 1,
) -> MPCResult:
    """One MPC episode of ``steps`` control steps from ``task.x0``, the first plan warm-started
    from U0 [H, nu] (H = task.T), replanning every ``replan_every`` control steps and
    applying the plan's policy in between, on ``plant`` (default: ``system``); ``progress``
    counts its control steps and can stop it (:func:`episode`). Arguments after U0 are
    keyword-only, as for every episode function of the package."""
    plant_step = (plant if plant is not None else system).step
    return ilqr_episode(
        d2c_replan(system, task, params, sysid, controller),
        plant_step,
        task,
        U0,
        key=key,
        steps=steps,
        process_noise=process_noise,
        progress=progress,
        replan_every=replan_every,
    )


def d2c_replan(
    system: BlackBox, task: Task, params: ILQRParams, sysid: sid.SysIdParams, controller: str = "d2c"
):
    """D2C-MPC's replan (or an oracle's: ``controller``), ``replan(x, plan, key, n) ->
    (Plan, (cost, iterations, identified))`` at control step n from the measured x [nx]:
    the horizon-H ``task`` planned at step n (:func:`~mjx_surrogate.tasks.at_step`); jit it
    to call it from outside an episode (:mod:`mjx_surrogate.control.realtime`)."""
    if controller not in CONTROLLERS:
        raise ValueError(f"controller: one of {', '.join(CONTROLLERS)}, got {controller!r}")

    def replan(x, plan, k, n):
        # knotted models (sysid.every > 1) stay knotted: no hand-over to every-step ones
        prob = problem(system, at_step(task, n).replace(x0=x), sysid, controller)  # "d2c" or an oracle
        prob = prob._replace(linearize_fine=None)
        return ilqr_replan(prob, plan, params, k)

    return replan


@functools.partial(jax.jit, static_argnames=("plant", "steps", "replan_every"))
def surrogate_mpc(
    model,
    task: Task,
    U0: jax.Array,
    *,
    plant: BlackBox,
    key: jax.Array,
    steps: int,
    params: ILQRParams = ILQRParams(max_iter=5),
    process_noise: float | jax.Array = 0.0,
    progress: ProgressMeter = NO_PROGRESS,
    replan_every: int = 1,
) -> MPCResult:
    """One episode on ``plant`` whose replans run iLQR on a differentiable surrogate (a
    pytree with ``step(x, u)``: a SindyModel, an MLPModel), Jacobians by ``jax.jacfwd``
    through it: SINDy-MPC, MLP-MPC. U0 [H, nu]; no black-box call but the plant's steps."""
    return ilqr_episode(
        surrogate_replanner(model, task, params),
        plant.step,
        task,
        U0,
        key=key,
        steps=steps,
        process_noise=process_noise,
        progress=progress,
        replan_every=replan_every,
    )


def ilqr_episode(
    replan, plant_step, task, plan0, *, key, steps, process_noise, progress, replan_every
) -> MPCResult:
    """:func:`episode` of an iLQR planner from its first warm start ``plan0`` (U0 [H, nu]: no
    feedback), its policy clipped to the task's limits."""
    if not hasattr(plan0, "K"):
        plan0 = first_plan(plan0, task.x0)
    X, U, (plan_cost, its, ident) = episode(
        replan,
        plant_step=plant_step,
        x0=task.x0,
        plan0=plan0,
        key=key,
        steps=steps,
        process_noise=process_noise,
        progress=progress,
        replan_every=replan_every,
        limits=(task.u_min, task.u_max),
    )
    return MPCResult(X, U, trajectory_cost(task, X, U), plan_cost, its, ident)


@functools.partial(jax.jit, static_argnames=("plant",))
def tracking(
    task: Task,
    X_ref: jax.Array,
    U_ref: jax.Array,
    K: jax.Array,
    *,
    plant: BlackBox,
    key: jax.Array,
    process_noise: float | jax.Array = 0.0,
) -> MPCResult:
    """TVLQR tracking of a fixed nominal X_ref [N+1, nx], U_ref [N, nu] with gains K [N, nu,
    nx]: u_n = clip(U_ref[n] + K[n] (x_n - X_ref[n])), no replanning; N steps from task.x0."""
    N = U_ref.shape[0]

    def control_step(x, inputs):
        x_ref, u_ref, K_n, k = inputs
        u = jnp.clip(u_ref + K_n @ (x - x_ref), task.u_min, task.u_max)
        k_noise = jax.random.split(k)[1]  # the draws of :func:`episode` from the same key
        x_next = plant.step(x, u) + process_noise * jax.random.normal(k_noise, x.shape, x.dtype)
        return x_next, (x, u)

    x0 = task.x0
    inputs = (
        X_ref[:N].astype(x0.dtype),
        U_ref.astype(x0.dtype),
        K.astype(x0.dtype),
        jax.random.split(key, N),
    )
    xN, (X, U) = jax.lax.scan(control_step, x0, inputs)
    X = jnp.concatenate([X, xN[None]])
    zeros = jnp.zeros((N,), x0.dtype)
    return MPCResult(
        X, U, trajectory_cost(task, X, U), zeros, zeros.astype(jnp.int32), jnp.zeros((N, 1), jnp.int8)
    )


def warm_start(prob: Problem, plan: Plan, params: ILQRParams, key: jax.Array):
    """The iLQR state a replan starts from (x0: the measured state): the cheaper of two
    rollouts of the shifted previous plan, its policy's, which feeds the measured state's
    deviation from the predicted one back through the previous gains (as MuJoCo MPC's
    iLQG does), and its controls' alone (the policy's can be the worse where the model
    changed since, e.g. refitted online)."""
    policy = ilqr_init(prob, plan.U, params, key, plan.X, plan.K)
    controls = ilqr_init(prob, plan.U, params, key)
    J_policy, J_controls = policy.solver.cost, controls.solver.cost
    better = jnp.isfinite(J_policy) & (J_policy <= J_controls)  # a blown-up policy's U may be NaN
    return jax.tree.map(lambda a, b: jnp.where(better, a, b), policy, controls)


def ilqr_replan(prob: Problem, plan: Plan, params: ILQRParams, key: jax.Array):
    """At most ``params.max_iter`` iLQR iterations on ``prob`` from :func:`warm_start`.
    -> (Plan, (cost, iterations, identified))."""
    r = ilqr_result(ilqr_advance(prob, warm_start(prob, plan, params, key), params))
    return Plan(r.U, r.X, r.K), (r.cost, r.iterations, r.identified)


def surrogate_replanner(model, task: Task, params: ILQRParams):
    """``replan(x, plan, key, n) -> (Plan, info)`` on the surrogate ``model``: the
    horizon-H ``task`` planned at control step n (:func:`surrogate_mpc`'s replan)."""

    def replan(x, plan, k, n):
        return surrogate_replan(model, at_step(task, n), x, plan, params, k)

    return replan


def surrogate_replan(model, task: Task, x: jax.Array, plan: Plan, params: ILQRParams, key: jax.Array):
    """One replan from x of iLQR on a differentiable surrogate ``model`` (a pytree with
    ``step(x, u)``), Jacobians by ``jax.jacfwd`` through it. -> as :func:`ilqr_replan`."""
    step = model.step
    prob = Problem(
        step, lambda X, U, K, k: sid.exact_jacobians(step, X, U), task_cost(task), x, task.u_min, task.u_max
    )
    return ilqr_replan(prob, plan, params, key)


def black_box_steps(result: MPCResult, horizon: int, n_alphas: int, sysid: sid.SysIdParams) -> np.ndarray:
    """Control steps simulated on the black box by each replan of a D2C episode [N]
    (identifications, the line search's trials and the two warm-start rollouts of
    :func:`ilqr_replan`), not counting the plant's own step."""
    per_id = steps_per_identification(sysid, horizon, result.U.shape[-1])
    ident, its = np.asarray(result.identified), np.asarray(result.iterations)
    return np.array(
        [horizon + simulation_curve(i, n, horizon, n_alphas, *per_id)[-1] for i, n in zip(ident, its)]
    )
