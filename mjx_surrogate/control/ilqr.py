"""Iterative LQR on any one-step map, as one ``lax.while_loop`` (paper, Preliminaries).

The solver sees only functions and fixed data: :class:`~mjx_surrogate.control.problem.Problem`
(the dynamics ``step``, the local model ``linearize``, the cost).

Backward pass: :func:`mjx_surrogate.control.riccati.backward_pass` (the Riccati sweep on the LTV
model, box-constrained k, regularisation mu).

Forward pass: u_t = clip(u_bar_t + alpha k_t + K_t (x_t - x_bar_t)), for ``n_alphas`` step
sizes alpha = alpha_factor^i, i = 0 .. n_alphas - 1, at once (vmap); a trial is accepted
when its cost is finite and (J - J_alpha) / (-(alpha dV1 + alpha^2 dV2)) > accept_ratio;
the best accepted trial wins.

When the model is identified, and when it is carried over instead (model reuse with
secant updates; coarse then fine identification), is decided by a model strategy
(:mod:`mjx_surrogate.control.model_strategies`, ``init``/``propose``/``update``); the model
and the strategies' states travel beside the solver's state (:class:`SolveState`), not in
it. One iteration reads: the strategy's proposal -> the model of the nominal -> backward
pass -> line search -> regularisation schedule -> the strategy's update -> stopping rules,
each a small function below.

Stopping rules (checked in this order after every iteration; :class:`StopReason`): a
local model that is not finite (the black box returned NaN or inf around the finite
nominal: diverged, the last finite iterate kept); relative cost decrease <= rel_tol;
max|k| <= k_tol (1 + max|U|); no trial accepted while the model promises
|dV| <= rel_tol |J| (the noise floor of the black box); in all three the decrease, k and
dV are first multiplied by 1 + reg (:func:`backward_pass`), as a heavily regularised step
is small, and gains little, without being optimal; a minimum rule that holds while the
cost is still the start's is ``STATIONARY``, not a convergence (the local model says the
controls do not lower the cost there: a start where the controls touch nothing, or a
start that is already a minimum); mu > mu_max (no descent found: stalled); max_iter; a
stop requested through the progress meter.

Regularisation schedule: mu falls by mu_factor after an accepted step and rises after a
rejected one; with mu_raise_alpha > 0 a step accepted only at a size below it raises mu
too, up to mu_max (a trust region on the step).

Feedback gains of the result (:func:`final_gains`): TVLQR of the final nominal on the last
model with the least regularisation that keeps Q_uu positive definite, computed once when
the solve stops.

One solve, one trace: :func:`ilqr`. The same loop in pieces, for a host that drives it:
:func:`ilqr_init` (the initial rollout), :func:`ilqr_advance` (iterate up to a given
iteration count, or mark the solve interrupted) and :func:`ilqr_result`; the functions and
fixed data of the problem travel together as a :class:`Problem`. A loop driven from the
host needs no host callback for its progress and stop requests, so its programs can be
kept in JAX's persistent compilation cache (:mod:`mjx_surrogate.control.chunked`).
"""

from __future__ import annotations

import enum
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
from flax import struct

from mjx_surrogate import progress as progress_lib
from mjx_surrogate.control import local_model
from mjx_surrogate.control.local_model import LocalModel, ModelState, full_gains
from mjx_surrogate.control.model_strategies import (
    ModelReport,
    ModelStrategy,
    StepOutcome,
    get_model_strategy,
    no_objection,
    no_proposal,
)
from mjx_surrogate.control.problem import ClosedLoopFn, LinearizeFn, Problem, StepFn
from mjx_surrogate.control.riccati import backward_pass, tvlqr_gains
from mjx_surrogate.cost import Cost, trajectory_cost
from mjx_surrogate.trajectory import feedback_rollout, feedback_rollouts

__all__ = [
    "Cost",
    "ILQRParams",
    "ILQRResult",
    "ILQRState",
    "Problem",
    "SolveState",
    "StopReason",
    "ilqr",
    "ilqr_advance",
    "ilqr_init",
    "ilqr_result",
    "trajectory_cost",
]


class StopReason(enum.IntEnum):
    """Why the solver stopped; ``verdict`` maps it to the status vocabulary."""

    RUNNING = 0
    COST_CHANGE = 1  # relative cost change below rel_tol
    SMALL_STEP = 2  # max |k| below k_tol
    MAX_ITER = 3
    NO_DESCENT = 4  # regularisation above mu_max, no descent found
    NOT_FINITE = 5  # initial cost not finite: the trajectory is not, or blew up (|x| > cost.BLOWUP)
    NOISE_FLOOR = 6  # expected decrease below rel_tol with no trial accepted
    INTERRUPTED = 7  # a stop was requested through the progress meter
    STATIONARY = 8  # a minimum rule held before any step lowered the cost below the start's
    MODEL_NOT_FINITE = 9  # the local model is not finite: the black box returned NaN/inf mid-solve

    @property
    def description(self) -> str:
        return _DESCRIPTIONS[self]

    @property
    def verdict(self) -> str:
        """converged | stationary | stalled | max_iter | diverged | interrupted | running."""
        return _VERDICTS[self]


_DESCRIPTIONS = {
    StopReason.RUNNING: "running",
    StopReason.COST_CHANGE: "relative cost change below rel_tol",
    StopReason.SMALL_STEP: "max |k| below k_tol",
    StopReason.MAX_ITER: "max_iter reached",
    StopReason.NO_DESCENT: "regularisation above mu_max (no descent found)",
    StopReason.NOT_FINITE: "initial trajectory not finite or beyond |x| = 1e8 (diverged)",
    StopReason.NOISE_FLOOR: "expected decrease below rel_tol (at the noise floor)",
    StopReason.INTERRUPTED: "interrupted (stop requested)",
    StopReason.STATIONARY: (
        "stationary start: no step lowered the cost below the start's before a minimum rule held "
        "(the controls' local effect on the cost vanishes there, or the start is already a minimum)"
    ),
    StopReason.MODEL_NOT_FINITE: (
        "the local model is not finite: the black box returned non-finite states around a finite "
        "nominal (diverged); the last finite iterate is kept"
    ),
}
_VERDICTS = {
    StopReason.RUNNING: "running",
    StopReason.COST_CHANGE: "converged",
    StopReason.SMALL_STEP: "converged",
    StopReason.NOISE_FLOOR: "converged",
    StopReason.MAX_ITER: "max_iter",
    StopReason.NO_DESCENT: "stalled",
    StopReason.NOT_FINITE: "diverged",
    StopReason.INTERRUPTED: "interrupted",
    StopReason.STATIONARY: "stationary",
    StopReason.MODEL_NOT_FINITE: "diverged",
}
CONVERGED = (StopReason.COST_CHANGE, StopReason.SMALL_STEP, StopReason.NOISE_FLOOR)


def verdict(stop_reason, cost) -> str:
    """The status of a finished solve: the stop reason's verdict, or ``diverged`` when the
    final cost is not finite."""
    cost = float(cost)
    if not (cost == cost and abs(cost) != float("inf")):
        return "diverged"
    return StopReason(int(stop_reason)).verdict


@struct.dataclass
class ILQRParams:
    """Stopping rules, regularisation schedule and line search. Floats are traced (no
    recompile when they change); the integer sizes are static."""

    rel_tol: float = 1e-6
    k_tol: float = 1e-5
    mu_init: float = 1e-6
    mu_min: float = 1e-8
    mu_max: float = 1e10
    mu_factor: float = 4.0
    accept_ratio: float = 1e-4
    alpha_factor: float = 0.5  # the line search's step sizes: alpha_factor ** (0 .. n_alphas - 1)
    mu_raise_alpha: float = 0.0  # an accepted step size below this raises mu as a rejection does
    # the default model strategy's settings (model_strategies.default_strategy)
    reuse_tol: float = 0.0  # reuse the model when |actual/expected decrease - 1| <= this
    reuse_max: int = 0  # at most this many iterations in a row on a reused model
    sysid_refine_tol: float = 0.0  # with linearize_fine: switch to it once a step gains <= this
    max_iter: int = struct.field(pytree_node=False, default=100)
    n_alphas: int = struct.field(pytree_node=False, default=8)
    record_trajectories: bool = struct.field(pytree_node=False, default=False)
    # a registered model strategy (model_strategies.MODEL_STRATEGIES) and its own settings
    model_strategy: str = struct.field(pytree_node=False, default="default")
    model_strategy_settings: Any = struct.field(pytree_node=False, default=None)


class ILQRResult(NamedTuple):
    """X [T+1, nx], U [T, nu], K [T, nu, nx], k [T, nu]; cost_history [max_iter+1]
    (NaN after the last iteration); X_history [max_iter+1, T+1, nx] if recorded;
    stop_reason a :class:`StopReason` value."""

    X: jax.Array
    U: jax.Array
    K: jax.Array
    k: jax.Array
    cost: jax.Array
    cost_history: jax.Array
    iterations: jax.Array
    stop_reason: jax.Array
    converged: jax.Array
    mu: jax.Array
    X_history: jax.Array
    alpha_history: jax.Array  # [max_iter] accepted step size per iteration (0: rejected)
    identified: jax.Array  # [max_iter] int8: 0 none, 1 ``linearize``, 2 ``linearize_fine``


def closed_loop(
    step: StepFn,
    x0: jax.Array,
    X_bar: jax.Array,
    U_bar: jax.Array,
    k: jax.Array,
    K: jax.Array,
    alpha: jax.Array,
    lo: jax.Array,
    hi: jax.Array,
) -> tuple[jax.Array, jax.Array]:
    """The forward pass of one step size: u_t = clip(u_bar_t + alpha k_t + K_t (x_t -
    x_bar_t)); returns X [T+1, nx], U [T, nu]."""
    return feedback_rollout(step, x0, X_bar, U_bar, K, alpha * k, lo, hi)


class ILQRState(NamedTuple):
    """The solver's own state (named as :class:`ILQRResult`'s fields): nominal X [T+1, nx],
    U [T, nu], gains K [T, nu, nx], k [T, nu], cost, regularisation mu, iterations done,
    stop reason, and the history."""

    X: jax.Array
    U: jax.Array
    K: jax.Array
    k: jax.Array
    cost: jax.Array
    mu: jax.Array
    iterations: jax.Array
    stop_reason: jax.Array
    cost_history: jax.Array  # [max_iter+1] cost after each iteration
    X_history: jax.Array
    alpha_history: jax.Array  # [max_iter] accepted step sizes


class SolveState(NamedTuple):
    """The loop's carry: the solver's state and, beside it, the local model's
    (:class:`~mjx_surrogate.control.local_model.ModelState`)."""

    solver: ILQRState
    model: ModelState


def strategy_of(problem: Problem, params: ILQRParams) -> ModelStrategy:
    """The problem's model strategy, else the registered one ``params.model_strategy``
    names (``"default"``: the default chain with the solver's settings)."""
    if problem.strategy is not None:
        return problem.strategy
    kind = get_model_strategy(params.model_strategy)
    return kind.make(params, problem.linearize_fine is not None, params.model_strategy_settings)


def ilqr_init(
    problem: Problem,
    U0: jax.Array,
    params: ILQRParams,
    key: jax.Array,
    X_ref: jax.Array | None = None,
    K_ref: jax.Array | None = None,
) -> SolveState:
    """The state before the first iteration: U0 [T, nu] clipped to the limits and rolled out.
    With a policy's X_ref [T+1, nx] and gains K_ref [T, nu, nx] (a receding horizon's previous
    plan), the rollout is closed-loop, u_t = clip(U0_t + K_ref_t (x_t - X_ref_t)), and its
    controls are the first nominal."""
    x0, u_min, u_max = problem.x0, problem.u_min, problem.u_max
    T, nu = U0.shape
    nx = x0.shape[0]
    dtype = x0.dtype
    U0 = jnp.clip(U0.astype(dtype), u_min, u_max)
    zeros_K = jnp.zeros((T, nu, nx), dtype)
    zeros_x = jnp.zeros((T + 1, nx), dtype)
    zeros_u = jnp.zeros((T, nu), dtype)
    policy = K_ref is not None
    X_bar = X_ref.astype(dtype) if policy else zeros_x
    K_bar = K_ref.astype(dtype) if policy else zeros_K
    if problem.trial_rollouts is None:
        X0, U_rolled = closed_loop(problem.step, x0, X_bar, U0, zeros_u, K_bar, 0.0, u_min, u_max)
    else:  # the line search's batched rollout with one step size: one host call, not T
        no_step = jnp.zeros((1,), dtype)
        X0, U_rolled = (
            a[0] for a in problem.trial_rollouts(x0, X_bar, U0, zeros_u, K_bar, no_step, u_min, u_max)
        )
    if policy:
        U0 = U_rolled
    J0 = trajectory_cost(problem.cost, X0, U0)
    n_hist = params.max_iter + 1
    X_hist = (
        jnp.full((n_hist, T + 1, nx), jnp.nan, dtype).at[0].set(X0)
        if params.record_trajectories
        else jnp.zeros((0,), dtype)
    )
    solver = ILQRState(
        X=X0,
        U=U0,
        K=zeros_K,
        k=jnp.zeros((T, nu), dtype),
        cost=J0,
        mu=jnp.asarray(params.mu_init, dtype),
        iterations=jnp.asarray(0),
        stop_reason=jnp.where(jnp.isfinite(J0), StopReason.RUNNING, StopReason.NOT_FINITE),
        cost_history=jnp.full((n_hist,), jnp.nan, dtype).at[0].set(J0),
        X_history=X_hist,
        alpha_history=jnp.zeros((params.max_iter,), dtype),
    )
    model = local_model.init_model(problem, strategy_of(problem, params), X0, U0, key, params.max_iter)
    return SolveState(solver, model)


class LineSearch(NamedTuple):
    """The forward pass's outcome: a trial was accepted; the nominal after it (X [T+1, nx],
    U [T, nu], cost J: the old one if none was); the accepted step size (0: none) and its
    actual / predicted decrease."""

    accepted: jax.Array
    X: jax.Array
    U: jax.Array
    J: jax.Array
    alpha: jax.Array
    ratio: jax.Array


def _line_search(problem: Problem, p: ILQRParams, s: ILQRState, k, K, dV, ok) -> LineSearch:
    """Roll out u_t = clip(u_bar_t + alpha k_t + K_t (x_t - x_bar_t)) for every step size at
    once; accept a finite trial whose decrease is more than accept_ratio of the model's
    promise -(alpha dV1 + alpha^2 dV2); the cheapest accepted trial wins."""
    x0, u_min, u_max = problem.x0, problem.u_min, problem.u_max
    dtype = x0.dtype
    alphas = jnp.asarray(p.alpha_factor, dtype) ** jnp.arange(p.n_alphas, dtype=dtype)
    if problem.trial_rollouts is None:
        Xa, Ua = feedback_rollouts(
            problem.step, x0, s.X, s.U, K, alphas[:, None, None] * k[None], u_min, u_max
        )
    else:
        Xa, Ua = problem.trial_rollouts(x0, s.X, s.U, k, K, alphas, u_min, u_max)
    Ja = jax.vmap(trajectory_cost, in_axes=(None, 0, 0))(problem.cost, Xa, Ua)
    expected = -(alphas * dV[0] + alphas**2 * dV[1])
    ratio = (s.cost - Ja) / jnp.where(expected > 0, expected, jnp.inf)
    accept = ok & jnp.isfinite(Ja) & (Ja < s.cost) & (ratio > p.accept_ratio)
    any_acc = jnp.any(accept)
    best = jnp.argmin(jnp.where(accept, Ja, jnp.inf))
    return LineSearch(
        accepted=any_acc,
        X=jnp.where(any_acc, Xa[best], s.X),
        U=jnp.where(any_acc, Ua[best], s.U),
        J=jnp.where(any_acc, Ja[best], s.cost),
        alpha=jnp.where(any_acc, alphas[best], 0.0),
        ratio=ratio[best],
    )


def _schedule(p: ILQRParams, mu: jax.Array, ls: LineSearch) -> jax.Array:
    """mu after the step: down by mu_factor after an accepted step, up after a rejected one.
    A step accepted only at a size below mu_raise_alpha says the model's Newton step reaches
    too far: it raises mu too (a trust region on the step), to at most mu_max, so that only
    rejections stop the solve there."""
    raised = jnp.maximum(mu * p.mu_factor, p.mu_min)
    short_step = ls.accepted & (ls.alpha < p.mu_raise_alpha)
    lowered = jnp.where(short_step, jnp.minimum(raised, p.mu_max), jnp.maximum(mu / p.mu_factor, p.mu_min))
    return jnp.where(ls.accepted, lowered, raised)


def _minimum_tests(p: ILQRParams, s: ILQRState, ls: LineSearch, k, dV, ok, reg) -> tuple:
    """(small cost change, small step, noise floor): the rules that declare a minimum. A
    small step, gain or promise means a minimum only if the regularisation did not make it
    small: each scales like 1 / (1 + reg), so they are judged undone. The noise floor: no
    trial accepted although the model promises almost nothing (the resolution of the black
    box / the LTV estimate)."""
    unreg = 1.0 + reg
    scale_u = 1.0 + jnp.max(jnp.abs(s.U))
    small_dJ = ls.accepted & (unreg * (s.cost - ls.J) <= p.rel_tol * jnp.abs(s.cost))
    small_k = ok & (unreg * jnp.max(jnp.abs(k)) < p.k_tol * scale_u)
    floor = ok & ~ls.accepted & (unreg * jnp.abs(dV[0] + dV[1]) <= p.rel_tol * jnp.abs(s.cost))
    return small_dJ, small_k, floor


def _stop_reason(
    p: ILQRParams, it, mu, model: LocalModel, report: ModelReport, minimum: tuple, moved, stop
) -> jax.Array:
    """The first rule that holds (:class:`StopReason`; RUNNING if none): a model that is not
    finite first; minima only on a model the strategies trust, and only once the cost has
    ``moved`` below the start's (else the start is stationary); a stall only on a fine model
    (:mod:`mjx_surrogate.control.model_strategies`)."""
    small_dJ, small_k, floor = minimum
    trusted = report.trusted
    at_min = trusted & (small_dJ | small_k | floor)
    return jnp.select(
        [
            ~local_model.model_finite(model),
            at_min & ~moved,
            trusted & small_dJ,
            trusted & small_k,
            trusted & floor,
            report.fine & (mu > p.mu_max),
            it >= p.max_iter,
            stop,
        ],
        [
            StopReason.MODEL_NOT_FINITE,
            StopReason.STATIONARY,
            StopReason.COST_CHANGE,
            StopReason.SMALL_STEP,
            StopReason.NOISE_FLOOR,
            StopReason.NO_DESCENT,
            StopReason.MAX_ITER,
            StopReason.INTERRUPTED,
        ],
        StopReason.RUNNING,
    )


def _iteration(problem: Problem, p: ILQRParams, progress, state: SolveState) -> SolveState:
    """One iLQR iteration: the strategy's proposal, the model of the nominal, backward pass,
    line search, regularisation schedule, the strategy's update, stopping rules."""
    s, m = state.solver, state.model
    strategy = strategy_of(problem, p)
    key, sub = jax.random.split(m.key)
    proposal = strategy.propose(m.strategy, no_proposal())
    model, how = local_model.make_model(problem, m.model, proposal, s.X, s.U, s.K, sub)
    k, K, dV, ok, reg = backward_pass(
        model.A, model.B, *model.expansion, s.U, problem.u_min, problem.u_max, s.mu
    )
    K = full_gains(K, model.V)
    ls = _line_search(problem, p, s, k, K, dV, ok)
    mu = _schedule(p, s.mu, ls)
    minimum = _minimum_tests(p, s, ls, k, dV, ok, reg)
    at_min = minimum[0] | minimum[1] | minimum[2]
    outcome = StepOutcome(ls.accepted, ls.ratio, at_min, mu > p.mu_max, s.cost, ls.J)
    strategies, report = strategy.update(m.strategy, proposal, outcome, no_objection())
    mu = jnp.where(report.handover, jnp.asarray(p.mu_init, mu.dtype), mu)  # a new model, a new schedule
    it = s.iterations + 1
    stop = progress_lib.poll(progress, it, ls.J, mu) if progress is not None else jnp.array(False)
    # judged on the model the step was taken on (a coarse one that handed over stops nothing)
    moved = ls.J < s.cost_history[0]  # the cost is below the start's
    reason = _stop_reason(p, it, mu, model, report, minimum, moved, stop)
    solver = ILQRState(
        X=ls.X,
        U=ls.U,
        K=jnp.where(ls.accepted, K, s.K),
        k=jnp.where(ls.accepted, k, s.k),
        cost=ls.J,
        mu=mu,
        iterations=it,
        stop_reason=reason,
        cost_history=s.cost_history.at[it].set(ls.J),
        X_history=s.X_history.at[it].set(ls.X) if p.record_trajectories else s.X_history,
        alpha_history=s.alpha_history.at[it - 1].set(ls.alpha),
    )
    return SolveState(solver, ModelState(model, strategies, key, m.identified.at[it - 1].set(how)))


def ilqr_advance(
    problem: Problem,
    state: SolveState,
    params: ILQRParams,
    until: jax.Array | int | None = None,
    stop: jax.Array | bool = False,
    progress: progress_lib.ProgressMeter | None = None,
) -> SolveState:
    """Iterate while the solve runs and fewer than ``until`` iterations are done (None:
    max_iter). ``stop`` True marks a running solve interrupted and iterates no more.
    ``progress``, if given, is polled from inside the loop once per iteration (a host
    callback); a host that drives the loop itself reports between calls instead."""
    until = params.max_iter if until is None else until
    s = state.solver
    interrupted = jnp.asarray(stop) & (s.stop_reason == StopReason.RUNNING)
    s = s._replace(stop_reason=jnp.where(interrupted, StopReason.INTERRUPTED, s.stop_reason))
    state = jax.lax.while_loop(
        lambda c: (c.solver.stop_reason == StopReason.RUNNING) & (c.solver.iterations < until),
        lambda c: _iteration(problem, params, progress, c),
        state._replace(solver=s),
    )
    s = state.solver
    finished = (s.stop_reason != StopReason.RUNNING) & (s.iterations > 0)
    K = jax.lax.cond(finished, lambda: final_gains(problem, state, params), lambda: s.K)
    return state._replace(solver=s._replace(K=K))


def final_gains(problem: Problem, state: SolveState, p: ILQRParams) -> jax.Array:
    """The feedback gains K [T, nu, nx] of a finished solve: TVLQR on the last model and
    the cost's expansion at the same nominal (the model's X, U: the final one unless
    the last step was accepted), with the least regularisation, 0 or else mu_min mu_factor^j up
    to mu_max, that makes every Q_uu positive definite (the solve's gains if none does).
    Not the last iteration's gains: mu B'B pushes those towards -(B'B)^-1 B'A, gains that
    cancel the dynamics: after a stall (mu past mu_max) a closed loop with them cost about
    twice the open loop under 1 % control noise (UR5e, dm_control humanoid)."""

    s, m = state.solver, state.model.model

    def gains(c):  # the loop holds the one call site, so the sweep is compiled once
        mu = jnp.where(c[0] < 0, 0.0, jnp.maximum(c[0] * p.mu_factor, p.mu_min))
        K, ok = tvlqr_gains(m.A, m.B, *m.expansion, m.U, problem.u_min, problem.u_max, mu)
        return mu, full_gains(K, m.V), ok

    start = (-jnp.ones((), s.X.dtype), s.K, jnp.array(False))
    _, K, ok = jax.lax.while_loop(lambda c: ~c[2] & (c[0] <= p.mu_max), gains, start)
    return jnp.where(ok, K, s.K)


def ilqr_result(state: SolveState) -> ILQRResult:
    """The result of a solve's state (its best iterate; ``stop_reason`` RUNNING if unfinished)."""
    s = state.solver
    converged = jnp.isin(s.stop_reason, jnp.asarray([int(r) for r in CONVERGED]))
    return ILQRResult(
        X=s.X,
        U=s.U,
        K=s.K,
        k=s.k,
        cost=s.cost,
        cost_history=s.cost_history,
        iterations=s.iterations,
        stop_reason=s.stop_reason,
        converged=converged,
        mu=s.mu,
        X_history=s.X_history,
        alpha_history=s.alpha_history,
        identified=state.model.identified,
    )


def ilqr(
    step: StepFn,
    linearize: LinearizeFn,
    cost: Cost,
    x0: jax.Array,
    U0: jax.Array,
    u_min: jax.Array,
    u_max: jax.Array,
    params: ILQRParams,
    key: jax.Array,
    trial_rollouts: ClosedLoopFn | None = None,
    progress: progress_lib.ProgressMeter | None = progress_lib.NO_PROGRESS,
    linearize_fine: LinearizeFn | None = None,
) -> ILQRResult:
    """Solve min_U J(x0, U) s.t. u_min <= u_t <= u_max. x0 [nx], U0 [T, nu] (the fields of
    :class:`Problem` for the rest). ``progress`` is polled once per iteration
    (:mod:`mjx_surrogate.progress`); a stop request ends the loop with
    ``StopReason.INTERRUPTED`` and the best iterate so far. None: no callback at all.

    Pure and traceable: wrap in ``jax.jit`` (with step/linearize/cost fixed) or ``vmap``
    over x0/U0/keys for multi-start solves.
    """
    problem = Problem(step, linearize, cost, x0, u_min, u_max, trial_rollouts, linearize_fine)
    state = ilqr_init(problem, U0, params, key)
    return ilqr_result(ilqr_advance(problem, state, params, progress=progress))
