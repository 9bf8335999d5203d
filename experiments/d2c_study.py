"""Experiment kind "d2c": data-driven iLQR on the black box against the exact oracle,
the LTV estimates against exact Jacobians, and the feedback policy under noise.

Stages (each written as it finishes, each figure as soon as its stages are): ``d2c``,
``exact`` (if enabled), ``ltv_error``, ``feedback``. The run's status is the D2C solve's verdict.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from mjx_surrogate import progress
from mjx_surrogate.analysis.evaluation import backed_off_feedback, evaluate_feedback
from mjx_surrogate.control import chunked
from mjx_surrogate.control.d2c import exact_linearize
from mjx_surrogate.identification import sysid, sysid_reduced
from mjx_surrogate.linalg import ltv_relative_error
from mjx_surrogate.runs import memory, pipeline, plots
from mjx_surrogate.runs.resolution import Resolved, solver_params
from mjx_surrogate.runs.results import Interrupted, Run
from mjx_surrogate.systems.system import actuated_state_indices
from mjx_surrogate.tasks import weight_diagonal


def ltv_error(system, X, U, K, key, sid_params, jacobians: str = "jacfwd") -> dict:
    """Relative Frobenius error of the LTV estimate [A B] against the oracle's Jacobians
    (jacfwd through MJX, or coordinate central differences), per t; a reduced model is
    compared with the Jacobians projected on its basis, V_{t+1}' [A_t B_t] (V_t 0; I).
    With the start given (a one-step scheme, ``perturb_x0`` off) A_0 is not identified
    and not used (dx_0 = 0): t = 0 compares B_0 alone."""
    model = jax.jit(sysid.ltv_linearize(system, sid_params))(X, U, K, key)
    Ae, Be = jax.jit(exact_linearize(system, jacobians))(X, U, K, key)
    out = {"scheme": sid_params.scheme}
    if len(model) == 3:
        A, B, V = model
        Ae, Be = jax.jit(sysid_reduced.project_model)(Ae, Be, V)
        out["basis_rank"] = [int(r) for r in sysid_reduced.basis_rank(V)]
    else:
        A, B = model
        if sysid.get_scheme(sid_params.scheme).one_step and not sid_params.perturb_x0:
            Ae = Ae.at[0].set(A[0])
    rel = np.asarray(ltv_relative_error(A, B, Ae, Be))
    return {"median": float(np.median(rel)), "max": float(np.max(rel)), **out}


def _names(prefix: str) -> tuple[str, str, str]:
    return f"{prefix}_U", f"{prefix}_X", f"{prefix}_K"


def _solve_arrays(prefix: str, result, X_bb) -> dict:
    out = {
        f"{prefix}_U": result.U,
        f"{prefix}_X": X_bb,
        f"{prefix}_K": result.K,
        f"{prefix}_cost_history": result.cost_history,
        f"{prefix}_identified": result.identified,
    }
    if result.X_history.ndim == 3:
        out[f"{prefix}_X_history"] = result.X_history
        out[f"{prefix}_alpha_history"] = result.alpha_history
    return out


def _shown_states(task, mj_model) -> list[int] | None:
    """The state coordinates of the trajectory figure: those the cost weighs, then the
    actuated ones; at most 16."""
    w = weight_diagonal(task.Q) + weight_diagonal(task.Q_f)
    weighted = [int(i) for i in np.nonzero(w > 0)[0][:8]]
    actuated = list(actuated_state_indices(mj_model)) if mj_model is not None else []
    return list(dict.fromkeys(weighted + actuated))[:16] or None


def run(res: Resolved, record: Run, key: jax.Array) -> str:
    cfg, system, task = res
    sc = cfg.solver
    # iterates are kept for the trajectory figure unless that would take > 80 MB (float64)
    params, sid_params = solver_params(
        cfg, record_trajectories=pipeline.record_history(sc.max_iter, task.T, system.nx)
    )
    _, _, k_ltv, k_noise = pipeline.experiment_keys(cfg.experiment.seed)
    record.add_arrays({"x0": task.x0})
    m_d2c, a_d2c = record.stage("d2c", lambda: _d2c_stage(res, sid_params))
    d2c_hist = a_d2c["d2c_cost_history"][: m_d2c["iterations"] + 1]
    _d2c_figures(record, res, m_d2c, a_d2c, sid_params)
    hist = {"D2C (LTV)": d2c_hist}
    exact_hist = _exact(record, res, params, sid_params, m_d2c, a_d2c, k_ltv)
    if exact_hist is not None:
        hist["exact Jacobians"] = exact_hist
    record.figure("cost_history.png", lambda: plots.cost_history(hist, f"{system.name}: {cfg.task.preset}"))
    _, a_fb = record.stage("feedback", lambda: _feedback_stage(res, a_d2c, k_noise, m_d2c["status"]))
    record.figure(
        "feedback_noise.png",
        lambda: plots.cost_vs_noise(
            np.asarray(cfg.experiment.noise_levels),
            {
                "closed loop (u* + K dx)": a_fb["feedback_closed_costs"],
                "open loop (u*)": a_fb["feedback_open_costs"],
            },
            f"{system.name}: cost under control noise",
        ),
    )
    return m_d2c["status"]


def _d2c_stage(res: Resolved, sid_params) -> tuple[dict, dict]:
    """The D2C solve of the config (multi-start if asked), its metrics and arrays."""
    cfg, system, task = res
    ex, sc = cfg.experiment, cfg.solver
    title = f"D2C multi-start x{sc.n_starts}" if sc.n_starts > 1 else "D2C (LTV identification + iLQR)"
    with progress.meter(title, sc.max_iter, ex.progress) as pm:
        sol = pipeline.solve_config(res, pm)
    timed, U0, costs, result = sol.timed, sol.U0, sol.costs, sol.timed.out
    extra = {}
    if costs is not None:  # every start's own end, before any search past a stall
        extra = {"multistart_costs": np.asarray(costs).tolist(), "multistart_statuses": list(sol.statuses)}
    m, X_bb = pipeline.summary(
        result, system, task, cfg.task.goal_tolerance, _names("d2c"), sol.restart, sol.search, sol.receding
    )
    m.update(
        extra,
        compile_s=timed.compile_s,
        run_s=timed.run_s,
        **pipeline.simulation_metrics(result, task.T, sc.n_alphas, sid_params),
    )
    return m, {"d2c_U0": U0, **_solve_arrays("d2c", result, X_bb)}


def _d2c_figures(record: Run, res: Resolved, m_d2c: dict, a_d2c: dict, sid_params) -> None:
    """Cost against black-box control steps, and the trajectories of the iterates."""
    cfg, system, task = res
    sc = cfg.solver
    n_it = m_d2c["iterations"]
    d2c_hist = a_d2c["d2c_cost_history"][: n_it + 1]
    per_id = pipeline.steps_per_identification(sid_params, task.T, task.u_min.shape[-1])
    curve = pipeline.simulation_curve(a_d2c["d2c_identified"], n_it, task.T, sc.n_alphas, *per_id)
    record.figure(
        "cost_vs_simulations.png",
        lambda: plots.cost_vs_simulations(
            {f"D2C ({sid_params.scheme}, n={sid_params.n_samples})": (curve, d2c_hist)},
            f"{system.name}: cost against black-box control steps",
        ),
    )
    t = np.arange(task.T + 1) * system.dt
    Xh = a_d2c.get("d2c_X_history", a_d2c["d2c_X"][None])[: n_it + 1]
    record.figure(
        "trajectory_evolution.png",
        lambda: plots.trajectory_evolution(
            t,
            Xh,
            np.asarray(task.x_goal),
            list(system.state_labels),
            f"D2C on {system.name} from {cfg.solver.init} controls",
            _shown_states(task, system.mj_model),
        ),
    )


def _exact(
    record: Run, res: Resolved, params, sid_params, m_d2c: dict, a_d2c: dict, k_ltv
) -> np.ndarray | None:
    """The oracle's solve from D2C's start and the LTV models' error against its Jacobians,
    if ``experiment.exact_oracle``; the oracle's cost history (None: not run or failed)."""
    cfg, system, task = res
    ex, sc = cfg.experiment, cfg.solver
    if not ex.exact_oracle:
        record.set(
            "exact", {"skipped": memory.oracle_off_reason(cfg.system.name, task, system.nx, system.nu)}
        )
        return None
    U0 = jnp.asarray(a_d2c["d2c_U0"])

    def exact_stage():
        with progress.meter("exact-Jacobian iLQR (oracle)", sc.max_iter, ex.progress) as pm:
            timed = chunked.solve_exact(system, task, U0, params, pm, ex.oracle)
        m, X_bb = pipeline.summary(timed.out, system, task, cfg.task.goal_tolerance, _names("exact"))
        m.update(compile_s=timed.compile_s, run_s=timed.run_s)
        return m, _solve_arrays("exact", timed.out, X_bb)

    try:
        m_ex, a_ex = record.stage("exact", exact_stage)
    except Interrupted:
        raise
    except Exception as exc:  # e.g. a user model using a feature MJX lacks
        record.set("exact", {"error": f"{type(exc).__name__}: {exc}"})
        return None
    c_d, c_e = m_d2c["cost"], m_ex["cost"]
    if c_d is not None and c_e is not None:
        record.set("d2c_vs_exact_relative_gap", (c_d - c_e) / abs(c_e))
    X, U, K = (jnp.asarray(a_d2c[k]) for k in ("d2c_X", "d2c_U", "d2c_K"))
    record.stage("ltv_relative_error", lambda: (ltv_error(system, X, U, K, k_ltv, sid_params, ex.oracle), {}))
    return a_ex["exact_cost_history"][: m_ex["iterations"] + 1]


def _feedback_stage(res: Resolved, a_d2c: dict, k_noise, status: str) -> tuple[dict, dict]:
    """The optimum under control noise, open loop (u*) and closed by its gains (u* + K dx);
    the gains' verdict (none for a solve of ``status`` stationary or diverged)."""
    cfg, system, task = res
    ex = cfg.experiment
    X, U, K = (jnp.asarray(a_d2c[k]) for k in ("d2c_X", "d2c_U", "d2c_K"))
    levels = jnp.asarray(ex.noise_levels, task.x0.dtype)
    closed, opened = evaluate_feedback(system, task, X, U, K, levels, k_noise, ex.n_noise_trials)
    closed, opened = np.asarray(closed), np.asarray(opened)
    m = {
        "noise_levels": list(ex.noise_levels),
        "noise": "std = level * U_max per channel (the actuator limit where finite, else max|u*|)",
        "closed_loop_median": np.median(closed, axis=1).tolist(),
        "open_loop_median": np.median(opened, axis=1).tolist(),
    }
    m["gains"] = pipeline.gains_verdict(
        ex.noise_levels, m["closed_loop_median"], m["open_loop_median"], status
    )
    m["gains_scale"] = 1.0
    arrays = {"feedback_closed_costs": closed, "feedback_open_costs": opened}
    # back off: the largest scale of K that helps (evaluation.backed_off_feedback)
    if m["gains"].startswith("do not use"):
        fb = backed_off_feedback(system, task, X, U, K, levels, k_noise, ex.n_noise_trials, (closed, opened))
        m["gains_scale"] = fb.scale
        if 0 < fb.scale < 1:
            m["backed_off_closed_loop_median"] = np.median(fb.closed, axis=1).tolist()
            backed = m["backed_off_closed_loop_median"]
            helps = pipeline.gains_verdict(ex.noise_levels, backed, m["open_loop_median"]) == "help"
            m["gains"] += f"; {fb.scale:g} x K " + ("helps" if helps else "does not help either")
            arrays["feedback_backed_off_costs"] = fb.closed
    return m, arrays
