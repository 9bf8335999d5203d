"""D2C-MPC with its LTV models carried from one replan to the next (``--mpc.d2c.reuse_tol``).

A replan of D2C-MPC (:func:`mpc.d2c_replan`) identifies the models of its warm start's
nominal before its first iteration, although the previous replan ended with models of
almost the same trajectory, one control step earlier. Here the plan carries its last
model, (A_t, B_t) [H, ...] of the nominal (X^m [H+1, nx], U^m [H, nu]) it was made on,
shifted on with the plan (its last stage repeated; :func:`consistent_nominal`). The next
replan tests it on the warm start's nominal (X, U): with dX = X - X^m and dU = U - U^m its
one-step prediction error e_t = dX_{t+1} - A_t dX_t - B_t dU_t must be a small part of the
change it predicts,

    sum_t |e_t|^2 <= reuse_tol^2 sum_t |dX_{t+1}|^2,

and the model must have been identified at most ``reuse_max`` replans ago. With models
identified at knots and interpolated between (``sysid.every`` > 1) the sums run over the
knots' stages only: an interpolated stage's error is the interpolation's, carried or not. Where both
hold, the replan's first iteration runs on the carried model, moved to the new nominal by
a secant update (:func:`~mjx_surrogate.control.local_model.secant_update`), instead of
identifying (the model strategy :func:`carried_first`); a step rejected on it is retried
on an identified model; a replan whose plan is already optimal on it stops there, with no
identification at all. Where either test fails, the replan is D2C-MPC's own. ``reuse_tol``
0 turns it off (:class:`D2CPlannerSettings`). Full-order models only (a reduced scheme's
basis changes from one replan to the next; refused in the config).
"""

from __future__ import annotations

import dataclasses
import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from mjx_surrogate.control.d2c import problem
from mjx_surrogate.control.episode import Plan
from mjx_surrogate.control.ilqr import ILQRParams, ilqr_advance, ilqr_result, strategy_of
from mjx_surrogate.control.model_strategies import ModelReport, ModelStrategy, Proposal, StepOutcome, chain
from mjx_surrogate.control.mpc import MPCResult, ilqr_episode, warm_start
from mjx_surrogate.errors import ConfigError
from mjx_surrogate.identification import sysid as sid
from mjx_surrogate.identification.sysid_knots import knot_times
from mjx_surrogate.progress import NO_PROGRESS, ProgressMeter
from mjx_surrogate.systems.black_box import BlackBox
from mjx_surrogate.tasks import Task, at_step


@dataclasses.dataclass(frozen=True)
class D2CPlannerSettings:
    """D2C-MPC's own settings (``--mpc.d2c.<field>``): carry the last replan's models over
    when their one-step prediction error is at most ``reuse_tol`` of the nominal's change
    (0: identify at every replan), for at most ``reuse_max`` replans in a row."""

    reuse_tol: float = 0.0
    reuse_max: int = 4

    def check(self) -> None:
        if not 0.0 <= self.reuse_tol < 1.0:
            raise ConfigError("reuse_tol", f"must be in [0, 1) (0: off), got {self.reuse_tol}")
        if self.reuse_max < 1:
            raise ConfigError("reuse_max", f"must be >= 1, got {self.reuse_max}")


class CarriedPlan(NamedTuple):
    """A :class:`~mjx_surrogate.control.episode.Plan` (U [H, nu], X [H+1, nx], K [H, nu, nx])
    with the model it ended on: A [H, nx, nx], B [H, nx, nu] of the nominal X_model [H+1,
    nx], U_model [H, nu]; ``age`` [H]: replans since that model was identified (every row
    the same, so the plan shifts as one; in the state's dtype, as every leaf of a plan);
    ``knots`` [H]: 1 where the model was identified, 0 where interpolated between knots
    (``sysid.every`` > 1), shifted with the plan."""

    U: jax.Array
    X: jax.Array
    K: jax.Array
    A: jax.Array
    B: jax.Array
    X_model: jax.Array
    U_model: jax.Array
    age: jax.Array
    knots: jax.Array


def first_carried_plan(U0: jax.Array, x0: jax.Array, reuse_max: int) -> CarriedPlan:
    """The first replan's warm start: U0 [H, nu], no feedback, no model (its age past
    ``reuse_max``, so the first replan identifies)."""
    (H, nu), nx, dt = U0.shape, x0.shape[0], x0.dtype
    return CarriedPlan(
        U0.astype(dt),
        jnp.zeros((H + 1, nx), dt),
        jnp.zeros((H, nu, nx), dt),
        jnp.zeros((H, nx, nx), dt),
        jnp.zeros((H, nx, nu), dt),
        jnp.zeros((H + 1, nx), dt),
        jnp.zeros((H, nu), dt),
        jnp.full((H,), reuse_max, dt),
        jnp.ones((H,), dt),
    )


def prediction_fits(A, B, dX, dU, tol, knots=None) -> jax.Array:
    """Whether the model (A [H, nx, nx], B [H, nx, nu]) predicts the nominal's change dX
    [H+1, nx] under dU [H, nu] one step at a time to within ``tol`` (module docstring), at
    the stages ``knots`` [H] marks (1; default: every stage)."""
    e = dX[1:] - jnp.einsum("tij,tj->ti", A, dX[:-1]) - jnp.einsum("tij,tj->ti", B, dU)
    w = jnp.ones(e.shape[:1], e.dtype) if knots is None else knots
    err, change = jnp.sum(w[:, None] * e * e), jnp.sum(w[:, None] * dX[1:] * dX[1:])
    return jnp.isfinite(err) & (err <= tol**2 * change)


def consistent_nominal(A, B, X, U, X_model, U_model) -> jax.Array:
    """The carried model's nominal X_model [H+1, nx] with the stages a shift repeated (x_{t+1}
    = x_t bit for bit: the model there is a copy of the last one, of no step the black box
    took) given the state that makes the model's prediction of the new nominal X [H+1, nx],
    U [H, nu] exact there, x^m_{t+1} = x_{t+1} - A_t (x_t - x^m_t) - B_t (u_t - u^m_t); such a
    stage is neither tested nor moved by the secant update."""
    copied = jnp.all(X_model[1:] == X_model[:-1], axis=-1)

    def stage(xm, inputs):
        A_t, B_t, x, x_next, du, xm_next, c = inputs
        xm_next = jnp.where(c, x_next - A_t @ (x - xm) - B_t @ du, xm_next)
        return xm_next, xm_next

    inputs = (A, B, X[:-1], X[1:], U - U_model, X_model[1:], copied)
    _, rest = jax.lax.scan(stage, X_model[0], inputs)
    return jnp.concatenate([X_model[:1], rest])


class CarriedState(NamedTuple):
    """The coming iteration is the first, on the carried model (``pending``); the last step
    was taken on it (``stale``)."""

    pending: jax.Array
    stale: jax.Array


def carried_first(carry: jax.Array) -> ModelStrategy:
    """Where ``carry`` holds, the first iteration runs on the model the solve starts with,
    secant-updated to the nominal, instead of an identified one; the next iteration
    identifies unless the strategies before it carry the model over after an accepted step.
    A minimum may be declared on the carried model (it passed the prediction test; a
    replan that ends there leaves the plan as it was). Last in a :func:`chain`."""

    def propose(s: CarriedState, p: Proposal) -> Proposal:
        identify = jnp.where(s.pending, False, p.identify | s.stale)
        return p._replace(identify=identify, carry=jnp.where(s.pending, True, p.carry & ~identify))

    def update(s: CarriedState, p: Proposal, o: StepOutcome, r: ModelReport):
        # the chain's secant reuse distrusts every carried model; this one passed its test
        trusted = r.trusted | s.pending
        return CarriedState(jnp.array(False), s.pending & ~o.accepted), r._replace(trusted=trusted)

    return ModelStrategy(
        init=lambda: CarriedState(jnp.asarray(carry), jnp.array(False)), propose=propose, update=update
    )


def reuse_replan(system: BlackBox, task: Task, params: ILQRParams, sysid: sid.SysIdParams, settings):
    """D2C-MPC's replan (:func:`mpc.d2c_replan`) with the models carried across replans:
    ``replan(x, plan, key, n) -> (CarriedPlan, (cost, iterations, identified))``;
    ``settings``: :class:`D2CPlannerSettings`."""

    H = task.T
    knot_mask = np.zeros(H)
    knot_mask[knot_times(H, sysid.every)] = 1.0

    def replan(x, plan: CarriedPlan, k, n):
        prob = problem(system, at_step(task, n).replace(x0=x), sysid, "d2c")._replace(linearize_fine=None)
        state = warm_start(prob, Plan(plan.U, plan.X, plan.K), params, k)
        X, U = state.solver.X, state.solver.U
        X_model = consistent_nominal(plan.A, plan.B, X, U, plan.X_model, plan.U_model)
        dX, dU = X - X_model, U - plan.U_model
        fits = prediction_fits(plan.A, plan.B, dX, dU, settings.reuse_tol, plan.knots)
        carry = fits & (plan.age[0] < settings.reuse_max) & (settings.reuse_tol > 0)
        strategy = chain(strategy_of(prob, params), carried_first(carry))
        prob = prob._replace(strategy=strategy)
        m = state.model.model._replace(A=plan.A, B=plan.B, X=X_model, U=plan.U_model)
        state = state._replace(model=state.model._replace(model=m, strategy=strategy.init()))
        end = ilqr_advance(prob, state, params)
        r, last = ilqr_result(end), end.model.model
        identified = jnp.any(r.identified > 0)
        age = jnp.where(identified, 0.0, plan.age + 1.0)
        knots = jnp.where(identified, jnp.asarray(knot_mask, plan.knots.dtype), plan.knots)
        out = CarriedPlan(r.U, r.X, r.K, last.A, last.B, last.X, last.U, age, knots)
        return out, (r.cost, r.iterations, r.identified)

    return replan


@functools.partial(jax.jit, static_argnames=("system", "steps", "settings", "plant", "replan_every"))
def carried_receding_horizon(
    system: BlackBox,
    task: Task,
    U0: jax.Array,
    *,
    key: jax.Array,
    steps: int,
    settings: D2CPlannerSettings,
    params: ILQRParams = ILQRParams(max_iter=5),
    sysid: sid.SysIdParams = sid.SysIdParams(),
    process_noise: float | jax.Array = 0.0,
    plant: BlackBox | None = None,
    progress: ProgressMeter = NO_PROGRESS,
    replan_every: int = 1,
) -> MPCResult:
    """:func:`mpc.receding_horizon` of D2C-MPC with its models carried across replans
    (:func:`reuse_replan`; ``settings``: :class:`D2CPlannerSettings`)."""
    return ilqr_episode(
        reuse_replan(system, task, params, sysid, settings),
        (plant if plant is not None else system).step,
        task,
        first_carried_plan(U0, task.x0, settings.reuse_max),
        key=key,
        steps=steps,
        process_noise=process_noise,
        progress=progress,
        replan_every=replan_every,
    )
