"""Steps that experiments compose: initial controls, the D2C optimum replayed on the
black box and its summary in the status vocabulary (the simulation count of a solve is
:mod:`mjx_surrogate.control.effort`'s, re-exported here).

These sit between the solvers (which see only functions) and ``experiments/`` (which
only compose library calls, write results and draw figures).
"""

from __future__ import annotations

import functools
import time
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from mjx_surrogate import progress
from mjx_surrogate.analysis import evaluation
from mjx_surrogate.analysis.closed_loop import in_goal_from
from mjx_surrogate.analysis.evaluation import finite_or_none
from mjx_surrogate.control import chunked
from mjx_surrogate.control.effort import simulation_curve, simulation_metrics, steps_per_identification  # noqa: F401
from mjx_surrogate.control.ilqr import ILQRParams, ILQRResult, StopReason, verdict
from mjx_surrogate.identification import data
from mjx_surrogate.identification import sysid as sid
from mjx_surrogate.progress import NO_PROGRESS, ProgressMeter
from mjx_surrogate.runs import native_replay
from mjx_surrogate.runs import sampling_search as search_lib
from mjx_surrogate.runs.model_defaults import hold_controls
from mjx_surrogate.runs.receding_pass import receding_pass
from mjx_surrogate.runs.resolution import solver_params
from mjx_surrogate.runs.restart import restart_stalled, restart_stationary, spread_starts
from mjx_surrogate.systems.black_box import BlackBox
from mjx_surrogate.systems.system_jit import system_jit
from mjx_surrogate.tasks import (
    Task,
    goal_cost,
    has_terminal,
    point_distances,
    trajectory_cost,
    weight_diagonal,
)
from mjx_surrogate.trajectory import open_loop


def initial_controls(
    key: jax.Array, T: int, nu: int, kind: str, scale: float, n: int | None = None, dtype=None
) -> jax.Array:
    """U0 [T, nu] (or [n, T, nu]): zeros, or N(0, scale^2) random controls."""
    shape = (T, nu) if n is None else (n, T, nu)
    dtype = dtype or jnp.asarray(0.0).dtype
    if kind == "zeros":
        return jnp.zeros(shape, dtype)
    return scale * jax.random.normal(key, shape, dtype)


def start_controls(
    system: BlackBox, task: Task, kind: str, scale: float, key: jax.Array, n: int | None = None
) -> jax.Array:
    """The solver's start U0 [T, nu] (or [n, T, nu] for n starts) of ``solver.init``:

    "zeros", "random" (N(0, scale^2)), "u_ref" (the task's control reference at every step)
    or "hold" (the controls that hold x0 still, :func:`model_defaults.hold_controls`). With
    several starts of a constant kind, start 0 is the constant and start i > 0 adds
    N(0, (scale * half range)^2) per control (half range 1 where unlimited), clipped to the
    limits: distinct starts, not one start repeated."""
    dtype = task.x0.dtype
    if kind in ("zeros", "random"):
        return initial_controls(key, task.T, system.nu, kind, scale, n, dtype)
    lo, hi = np.asarray(task.u_min, float), np.asarray(task.u_max, float)
    if kind == "u_ref":
        base = np.clip(np.asarray(task.u_ref, float), lo, hi)
    elif kind == "hold":
        base = hold_controls(system.mj_model, np.asarray(task.x0, float), lo, hi)
    else:
        raise ValueError(f"solver.init: unknown start {kind!r}; valid: zeros, random, u_ref, hold")
    U = jnp.broadcast_to(jnp.asarray(base, dtype), (task.T, system.nu))
    if n is None:
        return U
    first = jnp.clip(U, jnp.asarray(lo, dtype), jnp.asarray(hi, dtype))
    return spread_starts(task, U, key, n, scale).at[0].set(first)


def experiment_keys(seed: int) -> tuple[jax.Array, jax.Array, jax.Array, jax.Array]:
    """The keys of a d2c experiment with ``experiment.seed``: (start, identification,
    LTV error, feedback noise)."""
    return tuple(jax.random.split(jax.random.key(seed), 4))


class ConfigSolve(NamedTuple):
    timed: "chunked.Timed"  # .out: ILQRResult (the best start's with several), compile_s, run_s
    U0: jax.Array  # [T, nu] the start of the returned solve
    costs: jax.Array | None  # [n_starts] every start's final cost, or None for one start
    restart: dict | None = None  # what the restarts of a stationary or stalled solve did (runs.restart)
    search: dict | None = None  # what the sampling search did (mjx_surrogate.runs.sampling_search)
    receding: dict | None = None  # what the receding-horizon pass did (mjx_surrogate.runs.receding_pass)
    statuses: tuple[str, ...] | None = None  # [n_starts] every start's own verdict, or None for one start


def solve_config(res, progress: ProgressMeter = NO_PROGRESS) -> ConfigSolve:
    """The D2C solve of a resolved config exactly as ``python -m experiments.run`` makes it
    (solver settings, ``solver.init`` and ``n_starts``, keys from ``experiment.seed``):
    a notebook and the command line get the same controls and cost."""
    cfg, system, task = res
    sc = cfg.solver
    params, sid_params = solver_params(cfg, record_history(sc.max_iter, task.T, system.nx))
    k_init, k_d2c, _, _ = experiment_keys(cfg.experiment.seed)
    n = sc.n_starts if sc.n_starts > 1 else None
    U0 = start_controls(system, task, sc.init, sc.init_scale, k_init, n)
    rounds, restarts, tol = sc.sampling_search, sc.stationary_restarts, cfg.task.goal_tolerance
    return solve_from(
        system,
        task,
        U0,
        k_d2c,
        params,
        sid_params,
        rounds,
        restarts,
        tol,
        progress,
        sc.receding_pass,
        sc.stall_restarts or 0,
    )


def solve_from(
    system: BlackBox,
    task: Task,
    U0: jax.Array,
    key: jax.Array,
    params: ILQRParams,
    sysid: sid.SysIdParams,
    rounds: int,
    restarts: int,
    goal_tolerance: float,
    progress: ProgressMeter = NO_PROGRESS,
    receding: int = 0,
    stall_restarts: int = 0,
) -> ConfigSolve:
    """D2C from U0 [T, nu], or from each of U0 [n, T, nu] with the cheapest end kept, then
    :func:`past_a_stall` on the kept solve: the sampling search where it ended stationary or
    stalled short of its goal; the spread restarts (``restarts`` after a stationary end,
    ``stall_restarts`` after a stalled one) only after a single start (several starts were
    already the user's spread); then, with ``receding`` = H > 0, the receding-horizon pass
    over H steps (:mod:`~mjx_surrogate.runs.receding_pass`)."""
    timed = chunked.solve(system, task, U0, key, params, sysid, "d2c", progress)
    costs = statuses = None
    if U0.ndim == 3:
        out = timed.out
        costs, timed, U0 = out.costs, timed._replace(out=out.best), U0[int(out.best_index)]
        statuses = tuple(StopReason(int(r)).verdict for r in np.asarray(out.stop_reasons))
        restarts = stall_restarts = 0
    timed, U0, info, search = past_a_stall(
        system,
        task,
        timed,
        U0,
        key,
        params,
        sysid,
        rounds,
        restarts,
        goal_tolerance,
        progress,
        stall_restarts,
    )
    timed, U0, passed = receding_pass(system, task, timed, U0, key, params, sysid, receding, progress)
    return ConfigSolve(timed, U0, costs, info, search, passed, statuses)


def past_a_stall(
    system: BlackBox,
    task: Task,
    timed: "chunked.Timed",
    U0: jax.Array,
    key: jax.Array,
    params: ILQRParams,
    sysid: sid.SysIdParams,
    rounds: int,
    restarts: int,
    goal_tolerance: float,
    progress: ProgressMeter = NO_PROGRESS,
    stall_restarts: int = 0,
):
    """After a D2C solve from U0 (keys from ``key``, the solve's): the sampling search where
    it ended stationary or stalled short of its goal (judged by the goal test on the black
    box; :func:`~mjx_surrogate.runs.sampling_search.search_then_refine`), then, where
    the kept solve is still stationary, ``restarts`` spread starts, where it is stalled,
    ``stall_restarts`` starts spread around its start (:mod:`.restart`).
    Returns (the solve to keep, its start, the restarts' record, the search's record)."""
    search = None
    if rounds and StopReason(int(timed.out.stop_reason)).verdict in search_lib.NEEDED:
        X, _ = black_box_trajectory(system, task, timed.out.U)
        reached = goal_test(task, X, goal_tolerance)["reached"]
        k_search = jax.random.fold_in(key, 2)
        timed, U0, search = search_lib.search_then_refine(
            system, task, timed, U0, k_search, params, sysid, rounds, reached, progress
        )
    k_restart = jax.random.fold_in(key, 1)
    timed, U0, info = restart_stationary(
        system, task, timed, U0, k_restart, params, sysid, restarts, progress
    )
    if info is None:
        k_stall = jax.random.fold_in(key, 3)
        timed, U0, info = restart_stalled(
            system, task, timed, U0, k_stall, params, sysid, stall_restarts, progress
        )
    return timed, U0, info, search


NO_GAINS_VERDICT = ("stationary", "diverged")  # solves whose gains are not judged


def gains_verdict(levels, closed_median, open_median, status: str | None = None) -> str:
    """Whether the stored gains are to be used, from the median costs over draws at each
    noise level > 0: "help" when the closed loop u = U + K dx costs no more than the open
    loop at every level and less at one; "no effect" when it costs the same at every level
    (to 1e-9: gains that do not act); "do not use" naming the levels it makes worse (a
    closed loop that is not finite counts as worse); "not judged" where the open loop's
    median is not finite, or for a solve (``status``) that made no progress or diverged."""
    if status in NO_GAINS_VERDICT:
        return f"not judged: the solve is {status}"
    pairs = [(lv, float(c), float(o)) for lv, c, o in zip(levels, closed_median, open_median) if lv > 0]
    bad = [lv for lv, _, o in pairs if not np.isfinite(o)]
    if bad:
        return f"not judged: the open-loop cost is not finite at noise level(s) {bad}"
    if all(abs(c - o) <= 1e-9 * max(abs(o), 1e-300) for _, c, o in pairs):
        return "no effect: the closed loop costs the same as the open loop at every noise level"
    worse = evaluation.levels_made_worse(levels, closed_median, open_median)
    if not worse:
        return "help"
    return f"do not use: the closed loop costs more than the open loop at noise level(s) {worse}"


@system_jit(static_argnames=("system",))
def _replay_cost(system: BlackBox, task: Task, U: jax.Array) -> tuple[jax.Array, jax.Array]:
    X, Ua = open_loop(system.step, task.x0, U, task.u_min, task.u_max)
    return X, trajectory_cost(task, X, Ua)


# one compiled program per task structure, not an eager op (and a small compile) per
# cost term
_trajectory_cost = jax.jit(trajectory_cost)


@functools.partial(jax.jit, static_argnames=("terminal",))
def _goal_costs(task: Task, x0: jax.Array, xT: jax.Array, N, terminal: bool) -> tuple[jax.Array, jax.Array]:
    """The goal costs of x0 (moving targets at stage 0) and of xT (at stage N)."""
    return goal_cost(task, x0, terminal, 0), goal_cost(task, xT, terminal, N)


def black_box_trajectory(system: BlackBox, task: Task, U: jax.Array) -> tuple[jax.Array, float | None]:
    """U [T, nu] replayed from x0 on the black box: (X [T+1, nx], its cost or None)."""
    X, J = _replay_cost(system, task, U)
    return X, finite_or_none(J)


def unit_goal_cost(task: Task) -> float:
    """The goal cost of a unit error in every state coordinate and 1 m at every point goal:
    the scale of the goal test for a task that starts at its goal (a hold task)."""
    terminal = bool(np.any(np.asarray(task.Q_f))) or bool(np.any(np.asarray(task.final_weights)))
    W, w = (task.Q_f, task.final_weights) if terminal else (task.Q, task.weights)
    return 0.5 * float(np.sum(weight_diagonal(W))) + 0.5 * float(np.sum(np.asarray(w)))


def goal_passes(task: Task, X: jax.Array, tolerance: float) -> np.ndarray:
    """passes [N+1] (bool): the goal test of :func:`goal_test` applied to every state of X
    [N+1, nx] in turn, as if each were the last (moving targets where they are then)."""
    terminal = has_terminal(task)
    stages = jnp.arange(len(X), dtype=jnp.int32)
    costs = np.asarray(jax.vmap(lambda x, t: goal_cost(task, x, terminal, t))(jnp.asarray(X), stages), float)
    start = costs[0]
    bound = tolerance * (start if start > 0 else unit_goal_cost(task))
    return np.isfinite(costs) & (costs <= bound)


def episode_outcomes(task: Task, X: np.ndarray, costs, tolerance: float, dt: float) -> dict:
    """What a closed-loop row reports of its episodes X [E, N+1, nx] with costs [E]: the
    costs and their median, the share that passed the goal test, each episode's time from
    which every state passes it (None: not at the end), the median final goal cost and,
    with point goals, the goal points' mean distance from their targets over each
    episode's second half (median over episodes)."""
    goals = [goal_test(task, x, tolerance) for x in X]
    entered = [in_goal_from(goal_passes(task, x, tolerance)) for x in X]
    out = {
        "costs": [finite_or_none(c) for c in costs],
        "cost_median": finite_or_none(np.median(costs)),
        "goal_reached": sum(g["reached"] for g in goals) / len(goals),
        "in_goal_from_s": [None if n is None else n * dt for n in entered],
        "final_goal_cost_median": finite_or_none(np.median([g["goal_cost_final"] or np.inf for g in goals])),
    }
    if task.points is not None:  # how closely the loops follow
        half = X.shape[1] // 2
        errors = [float(np.mean(np.asarray(_point_distances(task, jnp.asarray(x)))[half:])) for x in X]
        out["point_error_median"] = finite_or_none(np.median(errors))
    return out


_point_distances = jax.jit(point_distances)


def goal_test(task: Task, X: jax.Array, tolerance: float) -> dict:
    """The goal test in the task's own weighted terms (:func:`tasks.goal_cost`): reached
    when goal_cost(x_T) <= tolerance * goal_cost(x_0); for a start at the goal (a hold
    task), when goal_cost(x_T) <= tolerance * :func:`unit_goal_cost`. Moving targets: x_0
    against the targets' start, x_T against where they are at the end of X [T+1, nx]."""
    N = jnp.asarray(len(X) - 1, jnp.int32)
    start, final = (float(v) for v in _goal_costs(task, X[0], X[-1], N, has_terminal(task)))
    bound = tolerance * (start if start > 0 else unit_goal_cost(task))
    return {
        "reached": bool(np.isfinite(final) and final <= bound),
        "goal_cost_final": finite_or_none(final),
        "goal_cost_start": finite_or_none(start),
        "tolerance": tolerance,
    }


def summary(
    result: ILQRResult,
    system: BlackBox,
    task: Task,
    goal_tolerance: float = 0.01,
    names: tuple[str, str, str] | None = None,
    restart: dict | None = None,
    search: dict | None = None,
    receding: dict | None = None,
) -> tuple[dict, jax.Array]:
    """Metrics of a solve in the status vocabulary, judged on the black box (``restart``:
    what :func:`~mjx_surrogate.runs.restart.restart_stationary` did before it, ``search``:
    what the sampling search did (:func:`past_a_stall`), each kept as is).

    ``cost`` is the cost of the solve's controls replayed on the black box (``cost_solver``
    the solver's own); ``status`` is the verdict of the stop reason (``diverged`` if the
    replayed cost is not finite); ``goal`` the goal test (:func:`goal_test`), which is
    separate from the status: a solve can converge to a point that misses the goal;
    ``native_float64`` the costs of the controls replayed on native MuJoCo in float64, open
    loop and closed loop around the replayed X with the solve's gains
    (:mod:`mjx_surrogate.runs.native_replay`; ``names``: the run's array names of U, X, K; None
    for a black box that is not a MuJoCo model), and
    ``replay_gap`` the relative difference of the one it judges by from ``cost``.
    Returns (metrics, the replayed X [T+1, nx]).
    """
    X_bb, cost = black_box_trajectory(system, task, result.U)
    reason = StopReason(int(result.stop_reason))
    cost_solver = finite_or_none(result.cost)
    status = verdict(reason, cost if cost is not None else np.inf)
    source = "black box replay"
    if (
        cost is None and cost_solver is not None
    ):  # the black box turned non-finite: keep the last finite iterate
        X_bb, cost, source = (
            result.X,
            cost_solver,
            "solver: the last finite iterate (its replay was not finite)",
        )
    out = {
        "status": status,
        "cost": cost,
        "cost_solver": cost_solver,
        "cost_source": source,
        "iterations": int(result.iterations),
        "converged": bool(result.converged),
        "stop_reason": reason.description,
        "goal": goal_test(task, X_bb, goal_tolerance),
        "controls_within_limits": bool(
            np.all(np.asarray(result.U) >= np.asarray(task.u_min))
            and np.all(np.asarray(result.U) <= np.asarray(task.u_max))
        ),
    }
    if status == "diverged" and cost is not None:
        last = int(result.iterations) - (reason == StopReason.MODEL_NOT_FINITE)
        out["last_finite_iteration"] = last
    if restart is not None:
        out["restart"] = restart
    if search is not None:
        out["sampling_search"] = search
    if receding is not None:
        out["receding_pass"] = receding
    if hint := status_hint(status, out):
        out["hint"] = hint
    if getattr(system, "mj_model", None) is None:  # a function black box: no MuJoCo to replay on
        out["native_float64"], out["replay_gap"] = None, None
        return out, X_bb
    native = native_replay.replay_costs(
        lambda X, U: finite_or_none(_trajectory_cost(task, jnp.asarray(X), jnp.asarray(U))),
        system.mj_model,
        system.substeps,
        np.asarray(task.x0),
        np.asarray(result.U),
        np.asarray(X_bb),
        np.asarray(result.K),
        np.asarray(task.u_min),
        np.asarray(task.u_max),
    )
    judged = native[native["judged_by"]]
    if names is not None:
        native["arrays"] = dict(zip(("U", "X", "K"), names))
    out["native_float64"] = native
    out["replay_gap"] = finite_or_none((judged - cost) / abs(cost)) if judged is not None and cost else None
    return out, X_bb


def status_hint(status: str, metrics: dict) -> str | None:
    """What to try after a solve that made no progress (also after its search and restarts),
    diverged, ran out of iterations, or converged at a point that misses its goal (None
    otherwise)."""
    if status == "stationary" and (restart := metrics.get("restart")) is not None:
        searched = "the sampling search and " if "sampling_search" in metrics else ""
        return (
            f"{searched}{restart['n_starts']} restarts spread over the actuators' range did not move it "
            "either (solver.sampling_search, solver.stationary_restarts): within this horizon the "
            "controls do not reach what the cost "
            "weighs; a longer horizon, a running cost that leads there, or more starts "
            "(--solver.n_starts 32 --solver.init_scale 1)"
        )
    if status == "stationary":
        return (
            "the local model says the controls do not lower the cost at the start (e.g. they touch "
            "nothing the cost weighs yet): try several starts spread over the actuators' range "
            "(--solver.n_starts 8 --solver.init_scale 1)"
        )
    if status == "diverged" and metrics.get("cost") is not None:
        last = metrics.get("last_finite_iteration")
        return (
            f"the black box returned non-finite states after iteration {last}; "
            "the controls and cost of that last finite iterate are kept"
        )
    goal = metrics.get("goal") or {}
    if status == "stalled":
        restart = metrics.get("restart") or {}
        tried = ""
        if restart.get("why") == "the first solve stalled":
            n, kept = restart["n_starts"], restart["kept"]
            if restart.get("n_asked", n) > n:
                n = f"{n} (a stop request ended the other {restart['n_asked'] - n})"
            tried = (
                f"{n} restarts around its start found no lower cost; "
                if kept.startswith("the first")
                else f"the kept solve is {kept} of {n} around its start, itself stalled; "
            )
        return (
            "no step the local models promised was granted by the black box (on a contact model: "
            f"contacts switching along the nominal; the oracle, experiment.exact_oracle, tells); {tried}"
            "try more starts (--solver.stall_restarts 8, or --solver.n_starts 8 --solver.init_scale 0.25) "
            "or more identification samples (--sysid.n_samples)"
        )
    if status == "max_iter":
        missed = " and its goal is not reached yet" if goal.get("reached") is False else ""
        return (
            f"the iteration budget ran out ({metrics.get('iterations')} iterations) before a stopping "
            f"rule held{missed}: the cost may still fall; give the solve room to finish "
            "(--solver.max_iter 1000)"
        )
    start, final = goal.get("goal_cost_start"), goal.get("goal_cost_final")
    if status == "converged" and goal.get("reached") is False and start and final is not None:
        return (
            f"converged at a point that misses the goal (its goal cost {100 * final / start:.3g} % of the "
            f"start's; the test asks {100 * goal['tolerance']:g} %): this local optimum trades the goal "
            "against the control effort and the running terms; weigh the goal more (Q_f, a point goal's "
            "final_weight), lower R or lengthen the horizon, unless the goal lies beyond the controls' reach"
        )
    return None


class Optimum(NamedTuple):
    result: ILQRResult
    X: jax.Array  # [T+1, nx] the optimum's controls replayed on the black box
    metrics: dict
    U0: jax.Array  # [T, nu] the start of the kept solve (a restart's, after a stationary or stalled one)


def d2c_optimum(
    system: BlackBox,
    task: Task,
    U0: jax.Array,
    key: jax.Array,
    params: ILQRParams,
    sysid: sid.SysIdParams,
    progress: ProgressMeter = NO_PROGRESS,
    goal_tolerance: float = 0.01,
    names: tuple[str, str, str] | None = None,
    restarts: int = 0,
    search_rounds: int = 0,
    receding: int = 0,
    stall_restarts: int = 0,
) -> Optimum:
    """Solve by D2C from U0 [T, nu], or from each of U0 [n, T, nu] keeping the cheapest
    (:func:`solve_from`: the sampling search, ``restarts`` spread starts past a
    stationary end and ``stall_restarts`` past a stalled one), and summarise on the black
    box (``names``: :func:`summary`; with several starts ``multistart_costs`` and
    ``multistart_statuses``, every start's own final cost and verdict, before any search
    past a stall); driven from the host
    (:mod:`mjx_surrogate.control.chunked`: cacheable programs). ``Optimum.U0``: the kept
    solve's start."""
    solved = solve_from(
        system,
        task,
        U0,
        key,
        params,
        sysid,
        search_rounds,
        restarts,
        goal_tolerance,
        progress,
        receding,
        stall_restarts,
    )
    metrics, X = summary(
        solved.timed.out, system, task, goal_tolerance, names, solved.restart, solved.search, solved.receding
    )
    if solved.costs is not None:
        metrics["multistart_costs"] = np.asarray(solved.costs).tolist()
        metrics["multistart_statuses"] = list(solved.statuses)
    return Optimum(solved.timed.out, X, metrics, solved.U0)


def record_history(max_iter: int, T: int, nx: int) -> bool:
    """Whether a solve keeps its iterates X_history: unless that exceeds 10^7 numbers."""
    return (max_iter + 1) * (T + 1) * nx <= 10_000_000


def optimum_stage(res, key: jax.Array):
    """A run stage (``Run.stage``) computing the task's D2C optimum from the config's
    initial controls (``solver.init``; the cheapest of ``solver.n_starts`` starts where
    more than one): (metrics, {X_star, U_star, K_star, U0_star (the kept start), u_max,
    X_history if kept (:func:`record_history`)})."""
    cfg, system, task = res
    sc = cfg.solver
    record_trajectories = record_history(sc.max_iter, task.T, system.nx)

    def compute():
        params, sid = solver_params(cfg, record_trajectories)
        k_init, k_d2c = jax.random.split(key)
        n = sc.n_starts if sc.n_starts > 1 else None
        U0 = start_controls(system, task, sc.init, sc.init_scale, k_init, n)
        t0 = time.perf_counter()
        with progress.meter("D2C optimum", sc.max_iter, cfg.experiment.progress) as pm:
            names = ("U_star", "X_star", "K_star")
            opt = d2c_optimum(
                system,
                task,
                U0,
                k_d2c,
                params,
                sid,
                pm,
                cfg.task.goal_tolerance,
                names,
                sc.stationary_restarts,
                sc.sampling_search,
                sc.receding_pass,
                sc.stall_restarts or 0,
            )
        m = {**opt.metrics, "wall_s": time.perf_counter() - t0}
        m |= simulation_metrics(opt.result, task.T, sc.n_alphas, sid)
        arrays = {
            "X_star": opt.X,
            "U_star": opt.result.U,
            "K_star": opt.result.K,
            "U0_star": opt.U0,
            "u_max": data.u_max(opt.result.U, task.u_min, task.u_max),
        }
        if record_trajectories:
            arrays["X_history"] = opt.result.X_history[: int(opt.result.iterations) + 1]
        return m, arrays

    return compute
