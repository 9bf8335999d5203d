"""Sampling, then D2C, where local models see nothing: the offline hybrid of a solve that
ended stationary or stalled short of its goal (MuJoCo MPC's iLQS order: sampling proposes,
iLQG refines).

A stationary solve stopped at its start (every local model says the controls do not move
the cost: dm_control's finger away from its spinner); a stalled one found no descent
where its local models, switching with the contacts along the nominal, stop agreeing with
the black box. Neither says where the goal is. The cross-entropy method on the black box
does not need them: ``solver.sampling_search`` rounds of S = 64 plans held at cubic spline
knots (one knot per 0.1 s of the horizon, 4 at least), spread at half of each actuator's
half range, the 8 cheapest kept as elites (:mod:`mjx_surrogate.control.mpc_sampling`,
:mod:`~mjx_surrogate.control.sampling_rules`), start at the solve's controls and end at the
elites' mean; D2C then solves from that mean. The refined solve is kept where it costs
less than the solve it follows. Both budgets are counted: (rounds x S + 1) x T black-box
control steps for the search (its plans and the mean's rollout), the refined solve's as
D2C's. Where the kept solve is still stationary, the spread restarts follow
(:func:`mjx_surrogate.runs.pipeline.past_a_stall`).
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from mjx_surrogate.control import chunked
from mjx_surrogate.control.effort import simulation_metrics
from mjx_surrogate.control.ilqr import ILQRParams, StopReason
from mjx_surrogate.control.mpc_sampling import (
    SamplingHyper,
    SamplingSettings,
    first_spline_plan,
    hyper,
    optimise,
)
from mjx_surrogate.identification import sysid as sid
from mjx_surrogate.progress import NO_PROGRESS, ProgressMeter
from mjx_surrogate.systems.black_box import BlackBox
from mjx_surrogate.tasks import Task, half_ranges, trajectory_cost
from mjx_surrogate.timing import Timed
from mjx_surrogate.trajectory import open_loop

SAMPLES = 64
ELITES = 8
SPREAD = 0.5  # of each actuator's half range
SPREAD_MIN = 0.02
NEEDED = ("stationary", "stalled")  # the verdicts after which the search runs (goal missed)


def search_settings(T: int, dt: float, rounds: int) -> SamplingSettings:
    """CEM over cubic spline knots, one knot per 0.1 s of the horizon (4 at least, T at most)."""
    knots = int(min(T, max(4, round(T * dt / 0.1))))
    return SamplingSettings("cem", SAMPLES, knots, "cubic", rounds, ELITES, 0)


@functools.partial(jax.jit, static_argnames=("system", "settings"))
def cem_search(
    system: BlackBox, task: Task, U: jax.Array, key: jax.Array, settings: SamplingSettings, h: SamplingHyper
) -> tuple[jax.Array, jax.Array]:
    """The elites' mean after ``settings.iterations`` rounds from U [T, nu] at spreads ``h``
    (module docstring): (its controls [T, nu], their cost on the black box)."""
    plan, _ = optimise(system, task, task.x0, first_spline_plan(U, settings, h.sigma), key, settings, h)
    Uc = jnp.clip(plan.U, task.u_min, task.u_max)
    return Uc, trajectory_cost(task, *open_loop(system.step, task.x0, Uc, task.u_min, task.u_max))


def search_then_refine(
    system: BlackBox,
    task: Task,
    timed: Timed,
    U0: jax.Array,
    key: jax.Array,
    params: ILQRParams,
    sysid: sid.SysIdParams,
    rounds: int,
    reached: bool,
    progress: ProgressMeter = NO_PROGRESS,
) -> tuple[Timed, jax.Array, dict | None]:
    """(the solve to keep, its start, what the search did or None): unchanged unless
    ``rounds`` > 0 and the solve ``timed.out`` ended stationary or stalled with its goal
    missed (``reached`` False); then the search from its controls and D2C from the search's
    plan, kept where it costs less."""
    first = timed.out
    status = StopReason(int(first.stop_reason)).verdict
    if rounds == 0 or reached or status not in NEEDED:
        return timed, U0, None
    k_search, k_solve = jax.random.split(key)
    settings = search_settings(task.T, system.dt, rounds)
    half = half_ranges(np.asarray(task.u_min), np.asarray(task.u_max))
    h = hyper(SPREAD * half, 1.0, SPREAD_MIN * half, first.U.dtype)
    U_s, J_s = cem_search(system, task, first.U, k_search, settings, h)
    refined = chunked.solve(system, task, U_s, k_solve, params, sysid, "d2c", progress)
    r = refined.out
    better = bool(np.isfinite(float(r.cost)) and float(r.cost) < float(first.cost))
    info = {
        "why": f"the solve was {status} and missed its goal",
        "search": f"CEM, {rounds} rounds of {SAMPLES} plans at {settings.knots} cubic spline knots, "
        f"{ELITES} elites, spread {SPREAD} x half range",
        "search_cost": float(J_s),
        "search_steps": (rounds * SAMPLES + 1) * task.T,  # the rounds' plans and the mean's rollout
        "refined_cost": float(r.cost),
        "refined_status": StopReason(int(r.stop_reason)).verdict,
        "refined_steps": simulation_metrics(r, task.T, params.n_alphas, sysid)["simulated_steps"],
        "kept": "the refined solve" if better else f"the {status} solve (the refined one cost no less)",
    }
    total = Timed(r if better else first, timed.compile_s + refined.compile_s, timed.run_s + refined.run_s)
    return total, (U_s if better else U0), info
