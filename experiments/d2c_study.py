"""Experiment kind "d2c": data-driven iLQR on the black box against the exact oracle,
the LTV estimates against exact Jacobians, and the feedback policy under noise."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from mjx_surrogate import plots, sysid
from mjx_surrogate.d2c import (exact_linearize, initial_controls, ltv_linearize,
                               simulated_steps, solve_d2c, solve_exact, solve_multistart)
from mjx_surrogate.feedback import evaluate_feedback
from mjx_surrogate.ilqr import STOP_REASONS
from mjx_surrogate.progress import progress_bar
from mjx_surrogate.results import RunFolder
from mjx_surrogate.rollout import rollout
from mjx_surrogate.setup import Resolved, solver_params
from mjx_surrogate.systems.system import state_labels
from mjx_surrogate.tasks import trajectory_cost
from mjx_surrogate.timing import compile_then_run


def _summary(res, timed, system, task, T, n_alphas, sid_params=None) -> dict:
    X_bb = rollout(system, task.x0[None], res.U[None])[0]  # replay on the black box
    cost_bb = float(trajectory_cost(task, X_bb, res.U))
    it = int(res.iterations)
    out = {"cost": cost_bb if np.isfinite(cost_bb) else None,
           "cost_solver": float(res.cost) if np.isfinite(float(res.cost)) else None,
           "iterations": it, "converged": bool(res.converged),
           "stop_reason": STOP_REASONS[int(res.stop_reason)],
           "compile_s": timed.compile_s, "run_s": timed.run_s,
           "final_state_error": float(jnp.linalg.norm(X_bb[-1] - task.x_goal))}
    if sid_params is not None:
        out["simulated_steps"] = simulated_steps(res, T, n_alphas, sid_params)
    return out, X_bb


def ltv_error(system, task, X, U, K, key, sid_params) -> dict:
    """Relative Frobenius error of the LTV estimate [A B] against jacfwd through MJX, per t."""
    A, B = jax.jit(ltv_linearize(system, sid_params))(X, U, K, key)
    Ae, Be = jax.jit(exact_linearize(system))(X, U, K, key)
    est = np.concatenate([np.asarray(A), np.asarray(B)], axis=-1)
    ex = np.concatenate([np.asarray(Ae), np.asarray(Be)], axis=-1)
    rel = np.linalg.norm(est - ex, axis=(1, 2)) / np.maximum(np.linalg.norm(ex, axis=(1, 2)), 1e-12)
    return {"median": float(np.median(rel)), "max": float(np.max(rel)),
            "scheme": sid_params.scheme}


def run(res: Resolved, folder: RunFolder, key: jax.Array) -> tuple[dict, dict]:
    cfg, system, task = res
    ex, sc = cfg.experiment, cfg.solver
    params, sid_params = solver_params(cfg, record_trajectories=True, progress=ex.progress)
    k_init, k_d2c, k_ltv, k_noise = jax.random.split(key, 4)
    dtype = task.x0.dtype
    metrics: dict = {"status": "ok"}
    arrays: dict = {"x0": task.x0}

    if sc.n_starts > 1:
        U0s = initial_controls(k_init, task.T, system.nu, sc.init, sc.init_scale, sc.n_starts, dtype)
        with progress_bar(f"D2C multi-start x{sc.n_starts}", sc.max_iter, ex.progress):
            ms = compile_then_run(solve_multistart, (system,),
                                  (task, U0s, k_d2c, params, sid_params))
        d2c = ms.out.best
        U0 = U0s[int(ms.out.best_index)]
        timed_d2c = ms
        metrics["multistart_costs"] = np.asarray(ms.out.costs).tolist()
    else:
        U0 = initial_controls(k_init, task.T, system.nu, sc.init, sc.init_scale, None, dtype)
        with progress_bar("D2C (LTV identification + iLQR)", sc.max_iter, ex.progress):
            timed_d2c = compile_then_run(solve_d2c, (system,), (task, U0, k_d2c, params, sid_params))
        d2c = timed_d2c.out
    arrays["d2c_U0"] = U0
    metrics["d2c"], X_d2c = _summary(d2c, timed_d2c, system, task, task.T, sc.n_alphas, sid_params)
    arrays.update(d2c_U=d2c.U, d2c_X=X_d2c, d2c_K=d2c.K, d2c_cost_history=d2c.cost_history,
                  d2c_alpha_history=d2c.alpha_history, d2c_X_history=d2c.X_history)
    if metrics["d2c"]["cost"] is None or int(d2c.stop_reason) in (4, 5):
        metrics["status"] = "diverged"

    timed_ex = None
    if not ex.exact_oracle:
        metrics["exact"] = {"skipped": "experiment.exact_oracle is false"}
    else:
        try:
            with progress_bar("exact-Jacobian iLQR (oracle)", sc.max_iter, ex.progress):
                timed_ex = compile_then_run(solve_exact, (system,), (task, U0, params))
        except Exception as exc:  # e.g. a user model using a feature MJX lacks
            metrics["exact"] = {"error": f"{type(exc).__name__}: {exc}"}
    if timed_ex is not None:
        exact = timed_ex.out
        metrics["exact"], X_ex = _summary(exact, timed_ex, system, task, task.T, sc.n_alphas)
        arrays.update(exact_U=exact.U, exact_X=X_ex, exact_K=exact.K,
                      exact_cost_history=exact.cost_history)
        c_d, c_e = metrics["d2c"]["cost"], metrics["exact"]["cost"]
        if c_d is not None and c_e is not None:
            metrics["d2c_vs_exact_relative_gap"] = (c_d - c_e) / abs(c_e)
        metrics["ltv_relative_error"] = ltv_error(system, task, d2c.X, d2c.U, d2c.K, k_ltv,
                                                  sid_params)

    levels = jnp.asarray(ex.noise_levels, dtype)
    closed, opened = evaluate_feedback(system, task, d2c.X, d2c.U, d2c.K, levels, k_noise,
                                       ex.n_noise_trials)
    closed, opened = np.asarray(closed), np.asarray(opened)
    metrics["feedback"] = {
        "noise_levels": list(ex.noise_levels), "noise": "std = level * max|u*| per channel",
        "closed_loop_median": np.nanmedian(closed, axis=1).tolist(),
        "open_loop_median": np.nanmedian(opened, axis=1).tolist()}
    arrays.update(feedback_closed_costs=closed, feedback_open_costs=opened)

    hist = {"D2C (LTV)": np.asarray(d2c.cost_history)[: int(d2c.iterations) + 1]}
    if timed_ex is not None:
        hist["exact Jacobians"] = np.asarray(exact.cost_history)[: int(exact.iterations) + 1]
    folder.write_figure("cost_history.png", plots.cost_history(hist, f"{system.name}: {cfg.task.preset}"))
    t = np.arange(task.T + 1) * system.dt
    Xh = np.asarray(d2c.X_history)[: int(d2c.iterations) + 1]
    folder.write_figure("trajectory_evolution.png", plots.trajectory_evolution(
        t, Xh, np.asarray(task.x_goal), state_labels(system.mj_model),
        f"D2C on {system.name} from {cfg.solver.init} controls"))
    folder.write_figure("feedback_noise.png", plots.cost_vs_noise(
        np.asarray(ex.noise_levels), {"closed loop (u* + K dx)": closed, "open loop (u*)": opened},
        f"{system.name}: cost under control noise"))
    return metrics, arrays
