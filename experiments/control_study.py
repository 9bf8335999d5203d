"""Experiment kind "control": optimal control with the global surrogates against the local
LTV approach (D2C) and the exact oracle, all judged by their true cost on the black box.

Stages: ``d2c`` (the optimum), ``exact`` (if enabled), then ``surrogates/<level>``:
``data.n_seeds`` data sets around the optimum, every kind of ``surrogate.kinds`` fitted on
each (the seeds at once where the kind can: the MLPs along a leading axis, over the
system's mesh), iLQR on each surrogate from the same start, its controls replayed on the
black box.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from mjx_surrogate import progress
from mjx_surrogate.analysis.evaluation import finite_or_none, replay
from mjx_surrogate.control import chunked
from mjx_surrogate.control.ilqr import StopReason
from mjx_surrogate.control.surrogate_control import solve_on_model
from mjx_surrogate.identification import data
from mjx_surrogate.runs import pipeline, plots
from mjx_surrogate.runs.extension_settings import settings_of
from mjx_surrogate.runs.resolution import Resolved, solver_params
from mjx_surrogate.runs.results import Run
from mjx_surrogate.surrogates import FitContext, fit_all_seeds

GOAL_RULE = "goal cost at x_T <= task.goal_tolerance x goal cost at x_0 (docs/results.md)"


def _surrogate_stage(res, X_d2c, U_d2c, U0, J_d2c, level, keys, params):
    cfg, system, task = res
    dc = cfg.data

    def compute():
        n = len(keys)
        n_steps = 1 + len(cfg.surrogate.kinds)  # + one per fitted model and seed, once known
        desc = f"surrogates {100 * level:g}% U_max, {n} seed{'s' if n > 1 else ''}"
        with progress.steps(desc, n_steps, cfg.experiment.progress) as meter:
            return _compute(meter)

    def _compute(meter):
        meter.advance(f"sample {len(keys)} x {dc.n_traj} trajectories")
        trains, tests = [], []
        for key in keys:
            ds = data.sample(system, X_d2c, U_d2c, key, dc.n_traj, level, dc.x0_sigma, task.u_min, task.u_max)
            train, test = data.split(ds, jax.random.fold_in(key, 1), dc.test_fraction)
            trains.append(data.transitions(train))
            tests.append(data.transitions(test))
        ctx = FitContext(cfg, system, task.T)
        fitted = fit_all_seeds(ctx, trains, tests, [jax.random.fold_in(k, 2) for k in keys], meter)
        rows, arrays = [], {}
        meter.extend(sum(len(f) for f in fitted))
        for seed, models in enumerate(fitted):
            for name, f in models.items():
                meter.advance(f"iLQR on {name}, seed {seed}, replay")
                row, row_arrays = _control_row(res, f.model, name, level, seed, U0, J_d2c, params)
                rows.append(row)
                arrays.update(row_arrays)
        return {"rows": rows}, arrays

    return compute


def _control_row(res, model, name, level, seed, U0, J_d2c, params):
    """iLQR on one fitted surrogate from U0, its controls replayed on the black box."""
    cfg, system, task = res
    sol = solve_on_model(model, task, U0, params)
    # on the host: the surrogate's arrays may live on the data set's device mesh,
    # the black box's model on one device
    sol = jax.tree.map(np.asarray, sol)
    out = replay(system, task, sol.X, sol.U, sol.K)
    row = {
        "model": name,
        "level": level,
        "seed": seed,
        "model_cost": finite_or_none(sol.cost),
        "iterations": int(sol.iterations),
        "true_cost_open": finite_or_none(out.cost_open),
        "true_cost_closed": finite_or_none(out.cost_closed),
        "final_error_open": finite_or_none(out.final_error_open),
        "final_error_closed": finite_or_none(out.final_error_closed),
    }
    best = min(v for v in (row["true_cost_open"], row["true_cost_closed"], np.inf) if v is not None)
    row["true_cost_over_d2c"] = best / J_d2c if np.isfinite(best) else None
    tol = cfg.task.goal_tolerance
    row["reached_goal"] = any(
        pipeline.goal_test(task, Xr, tol)["reached"] for Xr in (out.X_open, out.X_closed)
    )
    tag = f"{name.replace(' ', '_')}_{level:g}"
    row["arrays"] = {k: f"control_{tag}_s{seed}_{k}" for k in ("U", "X", "K")}
    arrays = {
        f"control_{tag}_s{seed}_U": sol.U,
        f"control_{tag}_s{seed}_X": sol.X,  # the model's nominal: closed loop needs it
        f"control_{tag}_s{seed}_K": sol.K,
        f"control_{tag}_s{seed}_X_closed": out.X_closed,
    }
    return row, arrays


def _starts_stage(res, n: int, key: jax.Array, params, sysid):
    """D2C and the oracle (where it is on) from n random starts of solver.init, solved along
    a leading axis: each start's D2C cost against the oracle's from the same start."""
    cfg, system, task = res
    ex, sc = cfg.experiment, cfg.solver

    def compute():
        k_init, k_solve = jax.random.split(key)
        U0s = pipeline.start_controls(system, task, sc.init, sc.init_scale, k_init, n)
        with progress.meter(f"D2C from {n} starts", sc.max_iter, ex.progress) as pm:
            d2c = chunked.solve(system, task, U0s, k_solve, params, sysid, "d2c", pm).out
        exact = None
        if ex.exact_oracle:
            with progress.meter(f"oracle from {n} starts", sc.max_iter, ex.progress) as pm:
                exact = chunked.solve_exact(system, task, U0s, params, pm, ex.oracle).out
        rows = []
        for i in range(n):
            row = {
                "start": i,
                "d2c_cost": finite_or_none(d2c.costs[i]),
                "d2c_status": StopReason(int(d2c.stop_reasons[i])).verdict,
                "d2c_iterations": int(d2c.iterations[i]),
            }
            if exact is not None:
                J = finite_or_none(exact.costs[i])
                row |= {"oracle_cost": J, "oracle_status": StopReason(int(exact.stop_reasons[i])).verdict}
                gap = None if J is None or row["d2c_cost"] is None else (row["d2c_cost"] - J) / abs(J)
                row["relative_gap"] = gap
            rows.append(row)
        return {"n": n, "rows": rows}, {"starts_U0": U0s, "starts_d2c_costs": d2c.costs}

    return compute


def run(res: Resolved, record: Run, key: jax.Array) -> str:
    cfg, system, task = res
    ex, sc, dc = cfg.experiment, cfg.solver, cfg.data
    params, sysid = solver_params(cfg)
    k_opt, k_data = jax.random.split(key)
    record.add_arrays({"x0": task.x0})
    record.set("goal_rule", GOAL_RULE)

    m_d2c, a_d2c = record.stage("d2c", pipeline.optimum_stage(res, k_opt))
    if m_d2c["cost"] is None:
        return "diverged"
    X_d2c, U_d2c = jnp.asarray(a_d2c["X_star"]), jnp.asarray(a_d2c["U_star"])
    U0 = jnp.asarray(a_d2c["U0_star"])
    J_d2c = m_d2c["cost"]
    m_d2c["reached_goal"] = m_d2c["goal"]["reached"]
    record.set("d2c", m_d2c)

    if ex.exact_oracle:

        def exact_stage():
            with progress.meter("exact-Jacobian iLQR (oracle)", sc.max_iter, ex.progress) as pm:
                exact = chunked.solve_exact(system, task, U0, params, pm, ex.oracle).out
            names = ("exact_U", "exact_X", "exact_K")
            m, X_ex = pipeline.summary(exact, system, task, cfg.task.goal_tolerance, names)
            return m, {"exact_U": exact.U, "exact_X": X_ex, "exact_K": exact.K}

        m_ex, _ = record.stage("exact", exact_stage)
        if m_ex["cost"] is not None:
            record.set("d2c_vs_exact_relative_gap", (J_d2c - m_ex["cost"]) / abs(m_ex["cost"]))

    n_starts = settings_of(cfg, "experiment", "control").starts
    if n_starts:
        m_starts, _ = record.stage(
            "starts", _starts_stage(res, n_starts, jax.random.fold_in(key, 3), params, sysid)
        )
        record.set("starts", m_starts)

    rows, trajectories = [], {}
    for i, level in enumerate(dc.levels):
        keys = [jax.random.fold_in(jax.random.fold_in(k_data, i), s) for s in range(dc.n_seeds)]
        out, arrays = record.stage(
            f"surrogates/{level:g}",
            _surrogate_stage(res, X_d2c, U_d2c, U0, J_d2c, level, keys, params),
        )
        rows += out["rows"]
        for r in out["rows"]:
            if r["seed"] == 0:
                tag = f"{r['model'].replace(' ', '_')}_{level:g}"
                trajectories[f"{r['model']} {100 * level:g}%"] = arrays[f"control_{tag}_s0_X_closed"]
    record.set("surrogate_rows", rows)
    t = np.arange(task.T + 1) * system.dt
    labels = list(system.state_labels)
    record.figure(
        "ltv_trajectory_evolution.png",
        lambda: plots.trajectory_evolution(
            t,
            a_d2c.get("X_history", a_d2c["X_star"][None]),
            np.asarray(task.x_goal),
            labels,
            f"LTV approach (D2C) on {system.name} from {sc.init} controls",
        ),
    )
    record.figure(
        "surrogate_controls.png",
        lambda: plots.predictions(
            t,
            np.asarray(X_d2c),
            trajectories,
            list(range(min(system.nq, 2))),
            labels,
            (list(system.angle_pairs) or [None])[0],
            f"{system.name}: surrogate-based controllers on the black box vs the D2C optimum",
        ),
    )
    record.folder.write_text("control_table.md", _table(record.metrics))
    return m_d2c["status"]


def _table(m: dict) -> str:
    f = lambda v: "diverged" if v is None else f"{v:.4g}"  # noqa: E731
    lines = [
        f"D2C (local LTV) true cost: {f(m['d2c']['cost'])}; exact oracle: "
        f"{f(m['exact'].get('cost')) if 'exact' in m else 'not run'}\n",
        *_starts_table(m.get("starts"), f),
        "| model | level (% U_max) | seed | cost on model | true cost open loop | "
        "true cost closed loop | true / D2C | reached goal |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in m["surrogate_rows"]:
        lines.append(
            f"| {r['model']} | {100 * r['level']:g} | {r['seed']} | {f(r['model_cost'])} | "
            f"{f(r['true_cost_open'])} | {f(r['true_cost_closed'])} | "
            f"{f(r['true_cost_over_d2c'])} | {r['reached_goal']} |"
        )
    return "\n".join(lines + _over_seeds(m["surrogate_rows"], f)) + "\n"


def _starts_table(starts: dict | None, f) -> list[str]:
    """D2C and the oracle from each random start (``experiment.control.starts``)."""
    if not starts:
        return []
    out = [
        f"From {starts['n']} random starts (`experiment.control.starts`), each solved by D2C and by "
        "the oracle:",
        "",
        "| start | D2C cost | D2C status | oracle cost | oracle status | D2C against the oracle |",
        "|---|---|---|---|---|---|",
    ]
    for r in starts["rows"]:
        gap = r.get("relative_gap")
        gap_text = "-" if gap is None else f"{100 * gap:+.3g} %"
        out.append(
            f"| {r['start']} | {f(r['d2c_cost'])} | {r['d2c_status']} | {f(r.get('oracle_cost'))} | "
            f"{r.get('oracle_status', 'not run')} | {gap_text} |"
        )
    return out + [""]


def _over_seeds(rows: list[dict], f) -> list[str]:
    """Per model and level, true / D2C over the seeds: median and range (a diverged replay
    counts as infinitely worse), and how many seeds reached the goal."""
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault((r["model"], r["level"]), []).append(r)
    if all(len(g) < 2 for g in groups.values()):
        return []
    out = [
        "",
        "Over the seeds (data sets and initialisations; a diverged replay counts as infinitely worse):",
        "",
        "| model | level (% U_max) | seeds | true / D2C, median | min - max | reached goal |",
        "|---|---|---|---|---|---|",
    ]
    for (model, level), g in groups.items():
        ratio = np.array([np.inf if r["true_cost_over_d2c"] is None else r["true_cost_over_d2c"] for r in g])
        shown = lambda v: "diverged" if not np.isfinite(v) else f(float(v))  # noqa: E731
        out.append(
            f"| {model} | {100 * level:g} | {len(g)} | {shown(np.median(ratio))} | "
            f"{shown(ratio.min())} - {shown(ratio.max())} | {sum(r['reached_goal'] for r in g)} of {len(g)} |"
        )
    return out
