"""Experiment kind "predict": the paper's prediction experiments.

1. The task's optimum (X*, U*) by D2C on the black box.
2. For each perturbation level: a data set of perturbed trajectories around it, split
   train : test by trajectory.
3. SINDy (each library), the MLP and the local LTV model fitted on the training set;
   one-step and open-loop multi-step predictions on the test trajectories.
"""

from __future__ import annotations

import time

import jax
import jax.numpy as jnp
import numpy as np

from mjx_surrogate import data, models, plots
from mjx_surrogate.d2c import initial_controls, solve_d2c
from mjx_surrogate.evaluation import prediction_errors
from mjx_surrogate.progress import progress_bar
from mjx_surrogate.results import RunFolder
from mjx_surrogate.rollout import rollout
from mjx_surrogate.setup import Resolved, library_specs, mlp_spec, solver_params
from mjx_surrogate.surrogates import mlp, sindy
from mjx_surrogate.systems.system import hinge_state_indices, state_labels
from mjx_surrogate.tasks import trajectory_cost


def optimum(res: Resolved, key: jax.Array, progress: bool) -> tuple[dict, jax.Array, jax.Array]:
    """The D2C optimum on the black box: (metrics, X* [T+1, nx], U* [T, nu])."""
    cfg, system, task = res
    sc = cfg.solver
    params, sid = solver_params(cfg, progress=progress)
    k_init, k_d2c = jax.random.split(key)
    U0 = initial_controls(k_init, task.T, system.nu, sc.init, sc.init_scale, None, task.x0.dtype)
    t0 = time.perf_counter()
    with progress_bar("D2C optimum", sc.max_iter, progress):
        out = jax.block_until_ready(solve_d2c(system, task, U0, k_d2c, params, sid))
    X = rollout(system, task.x0[None], out.U[None])[0]
    cost = float(trajectory_cost(task, X, out.U))
    m = {"cost": cost if np.isfinite(cost) else None, "iterations": int(out.iterations),
         "converged": bool(out.converged), "wall_s": time.perf_counter() - t0}
    return m, X, out.U


def fit_models(cfg, specs: dict, train: data.Dataset, test: data.Dataset, X_star, U_star,
               key: jax.Array) -> tuple[dict, dict]:
    """Every model of the comparison, as time-indexed steps, and its fit metrics."""
    s = cfg.surrogate
    tr, te = data.transitions(train), data.transitions(test)
    steps, info = {}, {}
    for name, spec in specs.items():
        t0 = time.perf_counter()
        model = sindy.fit(spec, tr.x, tr.u, tr.x_next, increment=s.increment,
                          threshold=s.stlsq_threshold, alpha=s.stlsq_alpha, method=s.sindy_method)
        jax.block_until_ready(model.coef)
        steps[f"SINDy {name}"] = models.time_invariant(model.step)
        info[f"SINDy {name}"] = {"fit_s": time.perf_counter() - t0, "n_features": int(model.coef.shape[0]),
                                 "nonzero": int(jnp.sum(model.coef != 0))}
    spec = mlp_spec(cfg)
    z = jnp.concatenate([tr.x, tr.u], -1)
    zt = jnp.concatenate([te.x, te.u], -1)
    t0 = time.perf_counter()
    result = mlp.train(spec, key, z, mlp.targets(tr.x, tr.x_next, spec.increment), zt,
                       mlp.targets(te.x, te.x_next, spec.increment))
    jax.block_until_ready(result.train_loss)
    steps["MLP"] = models.time_invariant(result.model.step)
    info["MLP"] = {"fit_s": time.perf_counter() - t0, "epochs": spec.epochs,
                   "final_train_loss": float(result.train_loss[-1]),
                   "final_test_loss": float(result.test_loss[-1])}
    t0 = time.perf_counter()
    ltv = models.fit_ltv(train, X_star, U_star)
    steps["LTV"] = ltv.step_t
    info["LTV"] = {"fit_s": time.perf_counter() - t0}
    return steps, info, result


def _rmse_table(levels, results: dict, key: str) -> str:
    names = list(next(iter(results.values())).keys())
    head = "| level (% U_max) | " + " | ".join(names) + " |\n|---|" + "---|" * len(names) + "\n"
    rows = []
    for lv in levels:
        r = results[f"{lv:g}"]
        cells = [f"{r[n][key]:.3g}" if r[n][key] is not None else "diverged" for n in names]
        rows.append(f"| {100 * lv:g} | " + " | ".join(cells) + " |")
    return head + "\n".join(rows) + "\n"


def run(res: Resolved, folder: RunFolder, key: jax.Array) -> tuple[dict, dict]:
    cfg, system, task = res
    ex, dc = cfg.experiment, cfg.data
    specs = library_specs(cfg, system)
    k_opt, k_levels = jax.random.split(key)
    metrics: dict = {"status": "ok", "u_max_definition": "largest |u*| per channel over the horizon"}
    m_opt, X_star, U_star = optimum(res, k_opt, ex.progress)
    metrics["optimum"] = m_opt
    arrays = {"X_star": X_star, "U_star": U_star, "u_max": data.u_max(U_star)}
    if m_opt["cost"] is None:
        metrics["status"] = "diverged"
        return metrics, arrays
    labels = state_labels(system.mj_model)
    t = np.arange(task.T + 1) * system.dt
    nq = system.mj_model.nq
    coords = list(range(min(nq, 3)))
    phase = (hinge_state_indices(system.mj_model) or [None])[0]
    results, train_curves = {}, {}
    for i, (level, k) in enumerate(zip(dc.levels, jax.random.split(k_levels, len(dc.levels)))):
        k_data, k_split, k_mlp = jax.random.split(k, 3)
        t0 = time.perf_counter()
        ds = jax.block_until_ready(data.sample(system, X_star, U_star, k_data, dc.n_traj, level,
                                               dc.x0_sigma))
        t_data = time.perf_counter() - t0
        train, test = data.split(ds, k_split, dc.test_fraction)
        steps, info, mlp_result = fit_models(cfg, specs, train, test, X_star, U_star, k_mlp)
        train_curves[f"{level:g}"] = (np.asarray(mlp_result.train_loss), np.asarray(mlp_result.test_loss))
        per_model, preds = {}, {}
        for name, step_t in steps.items():
            m, pred = prediction_errors(step_t, test)
            per_model[name] = {**m, **info[name]}
            preds[name] = pred[0]
        per_model["_data"] = {"sample_s": t_data, "n_train": int(train.X.shape[0]),
                              "n_test": int(test.X.shape[0])}
        results[f"{level:g}"] = per_model
        ok = np.asarray(jnp.isfinite(test.X).all((1, 2)))
        truth = np.asarray(test.X[ok][0])
        arrays[f"level{i}_test_X"] = truth
        for name, p in preds.items():
            arrays[f"level{i}_pred_{name.replace(' ', '_')}"] = p
        folder.write_figure(f"predict_{100 * level:g}pct.png", plots.predictions(
            t, truth, preds, coords, labels, phase,
            f"{system.name}: open-loop predictions, {100 * level:g}% U_max perturbations"))
    metrics["levels"] = list(dc.levels)
    metrics["results"] = results
    clean = {lv: {n: v for n, v in r.items() if not n.startswith("_")} for lv, r in results.items()}
    names = list(next(iter(clean.values())).keys())
    for key_, label in (("one_step_rmse", "one-step RMSE"), ("multi_step_median", "multi-step RMSE (median)")):
        errs = {n: [clean[f"{lv:g}"][n][key_] if clean[f"{lv:g}"][n][key_] is not None else np.nan
                    for lv in dc.levels] for n in names}
        folder.write_figure(f"{key_}_vs_level.png", plots.error_vs_level(
            np.asarray(dc.levels), errs, label, f"{system.name}: test {label}"))
    table = ("**One-step test RMSE**\n\n" + _rmse_table(dc.levels, clean, "one_step_rmse")
             + "\n**Open-loop multi-step test RMSE (median over test trajectories)**\n\n"
             + _rmse_table(dc.levels, clean, "multi_step_median"))
    folder.write_text("rmse_table.md", table)
    metrics["finding"] = _finding(dc.levels, clean)
    for lv, (tr, te) in train_curves.items():
        arrays[f"mlp_train_loss_{lv}"] = tr
        arrays[f"mlp_test_loss_{lv}"] = te
    return metrics, arrays


def _finding(levels, clean: dict) -> dict:
    """Does the global-model error grow with the level while the LTV stays accurate?"""
    out = {}
    lo, hi = f"{min(levels):g}", f"{max(levels):g}"
    for name in clean[lo]:
        a, b = clean[lo][name]["multi_step_median"], clean[hi][name]["multi_step_median"]
        out[name] = {"multi_step_median_lowest_level": a, "multi_step_median_highest_level": b,
                     "grows": (a is not None and b is not None and b > a) or (a is not None and b is None)}
    return out
