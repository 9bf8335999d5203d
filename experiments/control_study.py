"""Experiment kind "control": optimal control with the global surrogates against the local
LTV approach (D2C) and the exact oracle, all judged by their true cost on the black box."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from mjx_surrogate import data, plots
from mjx_surrogate.d2c import initial_controls, solve_d2c, solve_exact
from mjx_surrogate.progress import progress_bar
from mjx_surrogate.results import RunFolder
from mjx_surrogate.rollout import rollout
from mjx_surrogate.setup import Resolved, library_specs, mlp_spec, solver_params
from mjx_surrogate.surrogate_control import on_black_box, solve_on_model
from mjx_surrogate.surrogates import mlp, sindy
from mjx_surrogate.systems.system import hinge_state_indices, state_labels
from mjx_surrogate.tasks import trajectory_cost


def _num(v) -> float | None:
    v = float(v)
    return v if np.isfinite(v) else None


def run(res: Resolved, folder: RunFolder, key: jax.Array) -> tuple[dict, dict]:
    cfg, system, task = res
    ex, sc, dc = cfg.experiment, cfg.solver, cfg.data
    params, sid = solver_params(cfg, record_trajectories=True, progress=ex.progress)
    k_init, k_d2c, k_data = jax.random.split(key, 3)
    U0 = initial_controls(k_init, task.T, system.nu, sc.init, sc.init_scale, None, task.x0.dtype)
    with progress_bar("D2C (local LTV models)", sc.max_iter, ex.progress):
        d2c = jax.block_until_ready(solve_d2c(system, task, U0, k_d2c, params, sid))
    X_d2c = rollout(system, task.x0[None], d2c.U[None])[0]
    J_d2c = _num(trajectory_cost(task, X_d2c, d2c.U))
    scale = float(jnp.linalg.norm(task.x0 - task.x_goal))
    reached = lambda err: bool(err < 0.1 * scale)  # noqa: E731
    metrics: dict = {"status": "ok", "d2c": {"cost": J_d2c, "iterations": int(d2c.iterations),
                                             "final_state_error": _num(jnp.linalg.norm(X_d2c[-1] - task.x_goal))},
                     "goal_rule": "final-state error < 10 % of |x0 - x_goal|"}
    metrics["d2c"]["reached_goal"] = reached(metrics["d2c"]["final_state_error"] or np.inf)
    arrays = {"d2c_U0": U0, "d2c_U": d2c.U, "d2c_X": X_d2c, "d2c_K": d2c.K}
    if J_d2c is None:
        metrics["status"] = "diverged"
        return metrics, arrays
    if ex.exact_oracle:
        exact = solve_exact(system, task, U0, params)
        X_ex = rollout(system, task.x0[None], exact.U[None])[0]
        J_ex = _num(trajectory_cost(task, X_ex, exact.U))
        metrics["exact"] = {"cost": J_ex, "iterations": int(exact.iterations)}
        if J_ex is not None:
            metrics["d2c_vs_exact_relative_gap"] = (J_d2c - J_ex) / abs(J_ex)
        arrays["exact_U"] = exact.U

    t = np.arange(task.T + 1) * system.dt
    labels = state_labels(system.mj_model)
    Xh = np.asarray(d2c.X_history)[: int(d2c.iterations) + 1]
    folder.write_figure("ltv_trajectory_evolution.png", plots.trajectory_evolution(
        t, Xh, np.asarray(task.x_goal), labels, f"LTV approach (D2C) on {system.name} from {sc.init} controls"))

    specs = library_specs(cfg, system)
    spec_mlp = mlp_spec(cfg)
    rows, trajectories = [], {}
    for i, level in enumerate(dc.levels):
        for s in range(dc.n_seeds):
            k = jax.random.fold_in(jax.random.fold_in(k_data, i), s)
            ds = data.sample(system, X_d2c, d2c.U, k, dc.n_traj, level, dc.x0_sigma)
            train, test = data.split(ds, jax.random.fold_in(k, 1), dc.test_fraction)
            tr, te = data.transitions(train), data.transitions(test)
            fitted = {f"SINDy {n}": sindy.fit(sp, tr.x, tr.u, tr.x_next, increment=cfg.surrogate.increment,
                                              threshold=cfg.surrogate.stlsq_threshold,
                                              alpha=cfg.surrogate.stlsq_alpha,
                                              method=cfg.surrogate.sindy_method)
                      for n, sp in specs.items()}
            z = jnp.concatenate([tr.x, tr.u], -1)
            zt = jnp.concatenate([te.x, te.u], -1)
            fitted["MLP"] = mlp.train(spec_mlp, jax.random.fold_in(k, 2), z,
                                      mlp.targets(tr.x, tr.x_next, spec_mlp.increment), zt,
                                      mlp.targets(te.x, te.x_next, spec_mlp.increment)).model
            for name, model in fitted.items():
                sol = solve_on_model(model, task, U0, params)
                out = on_black_box(system, task, sol)
                row = {"model": name, "level": level, "seed": s,
                       "model_cost": _num(sol.cost), "iterations": int(sol.iterations),
                       "true_cost_open": _num(out.cost_open), "true_cost_closed": _num(out.cost_closed),
                       "final_error_open": _num(out.final_error_open),
                       "final_error_closed": _num(out.final_error_closed)}
                best = min(v for v in (row["true_cost_open"], row["true_cost_closed"], np.inf) if v is not None)
                row["true_cost_over_d2c"] = best / J_d2c if np.isfinite(best) else None
                row["reached_goal"] = reached(min(v for v in (row["final_error_open"],
                                                              row["final_error_closed"], np.inf)
                                                  if v is not None))
                rows.append(row)
                if s == 0:
                    trajectories[f"{name} {100 * level:g}%"] = np.asarray(out.X_closed)
                    arrays[f"control_{name.replace(' ', '_')}_{level:g}_U"] = sol.U
    metrics["surrogates"] = rows
    coords = list(range(min(system.nq, 2)))
    folder.write_figure("surrogate_controls.png", plots.predictions(
        t, np.asarray(X_d2c), trajectories, coords, labels, (hinge_state_indices(system.mj_model) or [None])[0],
        f"{system.name}: surrogate-based controllers on the black box vs the D2C optimum"))
    folder.write_text("control_table.md", _table(metrics))
    return metrics, arrays


def _table(m: dict) -> str:
    f = lambda v: "diverged" if v is None else f"{v:.4g}"  # noqa: E731
    lines = [f"D2C (local LTV) true cost: {f(m['d2c']['cost'])}; exact oracle: "
             f"{f(m.get('exact', {}).get('cost'))}\n",
             "| model | level (% U_max) | seed | cost on model | true cost open loop | "
             "true cost closed loop | true / D2C | reached goal |", "|---|---|---|---|---|---|---|---|"]
    for r in m["surrogates"]:
        lines.append(f"| {r['model']} | {100 * r['level']:g} | {r['seed']} | {f(r['model_cost'])} | "
                     f"{f(r['true_cost_open'])} | {f(r['true_cost_closed'])} | "
                     f"{f(r['true_cost_over_d2c'])} | {r['reached_goal']} |")
    return "\n".join(lines) + "\n"
