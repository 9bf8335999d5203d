"""Derivative-free receding-horizon control on the black box: a plan held at spline knots,
improved by sampling (predictive sampling, MPPI, CEM: :mod:`~.sampling_rules`).

A plan over H control steps is k knots y [k, nu] at times tau [k] (``splines.knot_times``:
spread from the plan's start to its horizon, or one at every step with ``knots`` 0) read
through a spline, U = W y with W = ``splines.basis(spline, tau, 0 .. H-1)`` [H, H or k].
A replan from the measured x_n (``optimise``) runs ``iterations`` times:

    y_i = clip(rule.sample(mean, spread)),  J_i = J(rollout of W y_i from x_n),  i < S
    (mean, spread) = rule.update(y, J)

and its plan is the final mean (the info: the last iteration's cheapest J_i). Between
replans the plant gets the plan's controls at its own steps; the next replan starts from
the spline moved on by the elapsed r steps (the knots re-read at tau + r, the spread kept),
as hydrax's planners advance their knot times. A replan simulates iterations x S x H
black-box control steps. With ``knots`` 0 every step is its own knot (W = I, the spline a
zero-order hold): predictive sampling then draws what it always drew, step by step.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from mjx_surrogate.control import splines
from mjx_surrogate.control.episode import episode
from mjx_surrogate.control.mpc import MPCResult
from mjx_surrogate.control.sampling_rules import SamplingHyper, get_rule
from mjx_surrogate.progress import NO_PROGRESS, ProgressMeter
from mjx_surrogate.systems.black_box import BlackBox
from mjx_surrogate.tasks import Task, at_step, trajectory_cost
from mjx_surrogate.trajectory import open_loop

__all__ = ["SamplingHyper", "SamplingSettings", "SplinePlan", "hyper", "optimise", "sampling_mpc"]


class SamplingSettings(NamedTuple):
    """A sampling planner's shapes (static): its ``rule`` (``sampling_rules.RULES``), S
    ``samples`` per iteration, ``knots`` (0: every step), the ``spline`` through them
    ("zero", "linear", "cubic"), ``iterations`` per replan, CEM's ``elites`` and its
    ``explore`` draws at the starting spread."""

    rule: str = "predictive_sampling"
    samples: int = 64
    knots: int = 0
    spline: str = "zero"
    iterations: int = 1
    elites: int = 3
    explore: int = 0


class SplinePlan(NamedTuple):
    """The sampling planner's plan: its controls U [H, nu] at the horizon's steps and the
    distribution they come from, knots ``mean`` and ``spread`` [k, nu]."""

    U: jax.Array
    mean: jax.Array
    spread: jax.Array


def hyper(sigma, temperature=1.0, sigma_min=0.0, dtype=None) -> SamplingHyper:
    """:class:`SamplingHyper` of plain numbers (``dtype``: the default float's)."""
    dtype = dtype or jnp.result_type(float)
    return SamplingHyper(*(jnp.asarray(v, dtype) for v in (sigma, temperature, sigma_min)))


def reading(H: int, knots: int, spline: str) -> np.ndarray | None:
    """W [H, knots]: the ``spline`` through ``knots`` knots read at the horizon's H steps;
    None for knots 0 (W = I, every step its own knot)."""
    if knots == 0:
        return None
    return splines.basis(spline, splines.knot_times(H, knots), np.arange(H))


def _matrices(H: int, s: SamplingSettings, r: int = 0, hold: bool = False):
    """(W [H, k] or None for W = I, M [k, k]: the knots moved on r steps, or None for r 0;
    ``hold``: past the last knot the spline's end value, not its extension)."""
    tau = splines.knot_times(H, s.knots)
    kind = "zero" if s.knots == 0 else s.spline
    t = np.minimum(tau + r, tau[-1]) if hold else tau + r
    M = splines.basis(kind, tau, t) if r else None
    return reading(H, s.knots, s.spline), M


def _read(W, mean):
    return mean if W is None else jnp.einsum("tk,kj->tj", jnp.asarray(W, mean.dtype), mean)


def first_spline_plan(U0: jax.Array, s: SamplingSettings, sigma) -> SplinePlan:
    """The plan whose spline is closest to U0 [H, nu] in least squares (U0 itself with
    ``knots`` 0), at spread ``sigma`` (scalar or [nu])."""
    W, _ = _matrices(U0.shape[0], s)
    mean = U0 if W is None else jnp.asarray(np.linalg.pinv(W), U0.dtype) @ U0
    spread = jnp.broadcast_to(jnp.asarray(sigma, U0.dtype), mean.shape)
    return SplinePlan(_read(W, mean), mean, spread)


def unbounded(task: Task) -> jax.Array:
    """[nu] bool: the actuators without both control limits, whose plans nothing clips."""
    return ~(jnp.isfinite(task.u_min) & jnp.isfinite(task.u_max))


def moved_on(plan: SplinePlan, r: int, s: SamplingSettings, free: jax.Array | None = None) -> SplinePlan:
    """The plan r control steps later: its spline re-read at the knot times plus r (beyond
    the horizon's end each spline's own extension: the last knot held, or extrapolated, as
    hydrax's splines do). On the actuators ``free`` [nu] marks (:func:`unbounded`) a linear
    or cubic spline's end value is held there instead: no clip bounds that extension, and
    from replan to replan it compounds."""
    if s.knots == 0:  # a knot per step: the plan shifted, its last control held
        mean = jnp.concatenate([plan.mean[r:], jnp.repeat(plan.mean[-1:], r, axis=0)])
        return SplinePlan(mean, mean, plan.spread)
    W, M = _matrices(plan.U.shape[0], s, r)
    mean = jnp.einsum("ik,kj->ij", jnp.asarray(M, plan.mean.dtype), plan.mean)
    if free is not None and s.spline != "zero":
        _, M_hold = _matrices(plan.U.shape[0], s, r, hold=True)
        held = jnp.einsum("ik,kj->ij", jnp.asarray(M_hold, plan.mean.dtype), plan.mean)
        mean = jnp.where(free, held, mean)
    return SplinePlan(_read(W, mean), mean, plan.spread)


def moved_on_host(
    plan: SplinePlan, r: int, s: SamplingSettings, free: np.ndarray | None = None
) -> SplinePlan:
    """:func:`moved_on` in NumPy, for the wall-clock loop (``control.realtime``); r may
    exceed the horizon H (a plan past its end holds its last control)."""
    H = plan.U.shape[0]
    if s.knots == 0:
        r = min(r, H)
        mean = np.concatenate([plan.mean[r:], np.repeat(plan.mean[-1:], r, axis=0)])
        return SplinePlan(mean, mean, plan.spread)
    W, M = _matrices(H, s, r)
    mean = M @ plan.mean if r else plan.mean
    if r and free is not None and s.spline != "zero":
        mean = np.where(free, _matrices(H, s, r, hold=True)[1] @ plan.mean, mean)
    return SplinePlan(W @ mean, mean, plan.spread)


def replanner(system: BlackBox, task: Task, settings: SamplingSettings, hyper: SamplingHyper):
    """``replan(x, plan, key, n) -> (plan, cheapest cost)``: :func:`optimise` of the
    horizon-H ``task`` at control step n (what :func:`sampling_mpc`'s episode calls)."""

    def replan(x, plan, k, n):
        return optimise(system, task, x, plan, k, settings, hyper, n)

    return replan


def optimise(
    system: BlackBox,
    task: Task,
    x: jax.Array,
    plan: SplinePlan,
    key: jax.Array,
    s: SamplingSettings,
    hyper: SamplingHyper,
    n: jax.Array | int = 0,
) -> tuple[SplinePlan, jax.Array]:
    """One replan from x [nx] at control step n: ``s.iterations`` rounds of sampling,
    rollouts on ``system`` and the rule's update (module docstring) -> (the plan, the last
    round's cheapest cost)."""
    rule, lo, hi = get_rule(s.rule), task.u_min, task.u_max
    W, _ = _matrices(plan.U.shape[0], s)
    planned = at_step(task, n)

    def cost(knots):
        return trajectory_cost(planned, *open_loop(system.step, x, _read(W, knots), lo, hi))

    def round_(carry, k):
        mean, spread = carry
        knots = jnp.clip(rule.sample(k, mean, spread, s.samples, s.explore, hyper), lo, hi)
        J = jax.vmap(cost)(knots)
        new = rule.update(knots, J, mean, spread, s.elites, hyper)
        # no finite rollout at all: keep the distribution rather than average infinities
        kept = jnp.any(jnp.isfinite(J))
        return jax.tree.map(lambda a, b: jnp.where(kept, a, b), new, (mean, spread)), jnp.min(J)

    keys = jax.random.split(key, s.iterations) if s.iterations > 1 else key[None]
    (mean, spread), J = jax.lax.scan(round_, (plan.mean, plan.spread), keys)
    return SplinePlan(_read(W, mean), mean, spread), J[-1]


@functools.partial(jax.jit, static_argnames=("system", "steps", "settings", "plant", "replan_every"))
def sampling_mpc(
    system: BlackBox,
    task: Task,
    U0: jax.Array,
    *,
    key: jax.Array,
    steps: int,
    settings: SamplingSettings,
    hyper: SamplingHyper,
    process_noise: float | jax.Array = 0.0,
    plant: BlackBox | None = None,
    progress: ProgressMeter = NO_PROGRESS,
    replan_every: int = 1,
) -> MPCResult:
    """One episode of ``steps`` control steps from ``task.x0`` (horizon H = task.T), the
    first plan U0 [H, nu] as a spline (:func:`first_spline_plan`), replanning every
    ``replan_every`` steps with :func:`optimise`."""
    plant_step = (plant if plant is not None else system).step
    X, U, J = episode(
        replanner(system, task, settings, hyper),
        plant_step=plant_step,
        x0=task.x0,
        plan0=first_spline_plan(U0.astype(task.x0.dtype), settings, hyper.sigma),
        key=key,
        steps=steps,
        process_noise=process_noise,
        progress=progress,
        replan_every=replan_every,
        shift=lambda plan, r: moved_on(plan, r, settings, unbounded(task)),
    )
    ones = jnp.full(J.shape, settings.iterations, jnp.int32)
    return MPCResult(X, U, trajectory_cost(task, X, U), J, ones, jnp.zeros(J.shape + (1,), jnp.int8))


def black_box_steps(settings: SamplingSettings, horizon: int) -> int:
    """Black-box control steps one replan simulates (not counting the plant's own steps)."""
    return settings.iterations * settings.samples * horizon
