"""Experiment kind "predict": the paper's prediction experiments.

1. Stage ``optimum``: the task's optimum (X*, U*) by D2C on the black box.
2. Stage ``results/<level>`` for each perturbation level: a data set of perturbed
   trajectories around it, split train : test by trajectory; every registered surrogate
   kind of ``surrogate.kinds`` and the local LTV model fitted on the training set;
   one-step and open-loop multi-step predictions on the test trajectories.
"""

from __future__ import annotations

import time
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from mjx_surrogate import progress
from mjx_surrogate.analysis import locality
from mjx_surrogate.analysis.evaluation import prediction_errors
from mjx_surrogate.identification import data, step_models, sysid
from mjx_surrogate.runs import pipeline, plots
from mjx_surrogate.runs.resolution import Resolved
from mjx_surrogate.runs.results import Run
from mjx_surrogate.surrogates import FitContext, fit_all


def level_stage(res: Resolved, X_star, U_star, level: float, i: int, key: jax.Array):
    """A stage: the data set at one level, every model fitted and evaluated."""
    cfg, system, task = res
    dc = cfg.data

    def compute():
        n_steps = len(cfg.surrogate.kinds) + 3
        with progress.steps(f"predict {100 * level:g}% U_max", n_steps, cfg.experiment.progress) as meter:
            return _compute(meter)

    def _compute(meter):
        k_data, k_split, k_fit = jax.random.split(key, 3)
        meter.advance(f"sample {dc.n_traj} trajectories")
        t0 = time.perf_counter()
        lim = (task.u_min, task.u_max)
        ds = data.sample(system, X_star, U_star, k_data, dc.n_traj, level, dc.x0_sigma, *lim)
        ds = jax.block_until_ready(ds)
        t_data = time.perf_counter() - t0
        train, test = data.split(ds, k_split, dc.test_fraction)
        fitted = fit_all(
            FitContext(cfg, system, task.T), data.transitions(train), data.transitions(test), k_fit, meter
        )
        steps = {name: step_models.as_pytree(f.model) for name, f in fitted.items()}
        info = {name: f.info for name, f in fitted.items()}
        meter.advance("fit LTV")
        t0 = time.perf_counter()
        steps["LTV"] = step_models.fit_ltv(train, X_star, U_star).as_pytree()
        info["LTV"] = {"fit_s": time.perf_counter() - t0}
        if cfg.surrogate.reduced_ltv_tol is not None:
            t0 = time.perf_counter()
            tol = cfg.surrogate.reduced_ltv_tol
            steps["LTV reduced"] = step_models.fit_reduced_ltv(train, X_star, U_star, tol).as_pytree()
            info["LTV reduced"] = {"fit_s": time.perf_counter() - t0}
        meter.advance("prediction errors")
        per_model, arrays = {}, {}
        arrays[f"level{i}_test_X"] = data.finite_trajectories(test).X[0]
        for name, step_t in steps.items():
            m, pred = prediction_errors(step_t, test)
            per_model[name] = {**m, **info[name]}
            arrays[f"level{i}_pred_{name.replace(' ', '_')}"] = pred[0]
        for name, f in fitted.items():
            for k, v in f.arrays.items():
                arrays[f"{name.replace(' ', '_').lower()}_{k}_{level:g}"] = v
        per_model["_data"] = {
            "sample_s": t_data,
            "n_train": int(train.X.shape[0]),
            "n_test": int(test.X.shape[0]),
            "relative_spread": float(locality.relative_spread(ds.X, X_star)),
        }
        return per_model, arrays

    return compute


@partial(jax.jit, static_argnums=0)
def _open_loop_gain(system, X_star, U_star):
    """The optimum's open-loop gain through its coordinate finite-difference linearisation
    on the black box (:mod:`mjx_surrogate.analysis.locality`)."""
    A, B = sysid.finite_difference_jacobians(system.step, X_star, U_star)
    return locality.open_loop_gain(A, B)


def _rmse_table(levels, results: dict, key: str) -> str:
    names = list(next(iter(results.values())).keys())
    head = "| level (% U_max) | " + " | ".join(names) + " |\n|---|" + "---|" * len(names) + "\n"
    rows = []
    for lv in levels:
        r = results[f"{lv:g}"]
        cells = [f"{r[n][key]:.3g}" if r[n][key] is not None else "diverged" for n in names]
        rows.append(f"| {100 * lv:g} | " + " | ".join(cells) + " |")
    return head + "\n".join(rows) + "\n"


def run(res: Resolved, record: Run, key: jax.Array) -> str:
    cfg, system, task = res
    dc = cfg.data
    k_opt, k_levels = jax.random.split(key)
    record.set("u_max_definition", "the actuator limit where finite, else the largest |u*| per channel")
    record.add_arrays({"x0": task.x0})
    m_opt, a_opt = record.stage("optimum", pipeline.optimum_stage(res, k_opt))
    if m_opt["cost"] is None:
        return "diverged"
    X_star, U_star = jnp.asarray(a_opt["X_star"]), jnp.asarray(a_opt["U_star"])
    labels = list(system.state_labels)
    t = np.arange(task.T + 1) * system.dt
    coords = list(range(min(system.nq, 3)))
    phase = (list(system.angle_pairs) or [None])[0]
    results = {}
    for i, (level, k) in enumerate(zip(dc.levels, jax.random.split(k_levels, len(dc.levels)))):
        per_model, arrays = record.stage(f"results/{level:g}", level_stage(res, X_star, U_star, level, i, k))
        results[f"{level:g}"] = per_model
        preds = {
            n: arrays[f"level{i}_pred_{n.replace(' ', '_')}"] for n in per_model if not n.startswith("_")
        }
        record.figure(
            f"predict_{100 * level:g}pct.png",
            lambda: plots.predictions(
                t,
                arrays[f"level{i}_test_X"],
                preds,
                coords,
                labels,
                phase,
                f"{system.name}: open-loop predictions, {100 * level:g}% U_max perturbations",
            ),
        )
    record.set("levels", list(dc.levels))
    gain = float(_open_loop_gain(system, X_star, U_star))
    spread = [results[f"{lv:g}"]["_data"]["relative_spread"] for lv in dc.levels]
    record.set(
        "locality",
        {
            "open_loop_gain": gain,
            "relative_spread": dict(zip((f"{lv:g}" for lv in dc.levels), spread)),
            "definition": "docs/method.md#locality",
        },
    )
    record.figure(
        "locality.png",
        lambda: plots.locality(
            np.asarray(dc.levels), np.asarray(spread), gain, f"{system.name}: data locality"
        ),
    )
    clean = {lv: {n: v for n, v in r.items() if not n.startswith("_")} for lv, r in results.items()}
    names = list(next(iter(clean.values())).keys())
    for key_, label in (
        ("one_step_rmse", "one-step RMSE"),
        ("multi_step_median", "multi-step RMSE (median)"),
    ):
        errs = {
            n: [
                clean[f"{lv:g}"][n][key_] if clean[f"{lv:g}"][n][key_] is not None else np.nan
                for lv in dc.levels
            ]
            for n in names
        }
        record.figure(
            f"{key_}_vs_level.png",
            lambda: plots.error_vs_level(np.asarray(dc.levels), errs, label, f"{system.name}: test {label}"),
        )
    record.folder.write_text(
        "rmse_table.md",
        (
            "**One-step test RMSE**\n\n"
            + _rmse_table(dc.levels, clean, "one_step_rmse")
            + "\n**Open-loop multi-step test RMSE (median over test trajectories)**\n\n"
            + _rmse_table(dc.levels, clean, "multi_step_median")
        ),
    )
    record.set("finding", _finding(dc.levels, clean))
    return m_opt["status"]


def _finding(levels, clean: dict) -> dict:
    """Does the global-model error grow with the level while the LTV stays accurate?"""
    out = {}
    lo, hi = f"{min(levels):g}", f"{max(levels):g}"
    for name in clean[lo]:
        a, b = clean[lo][name]["multi_step_median"], clean[hi][name]["multi_step_median"]
        out[name] = {
            "multi_step_median_lowest_level": a,
            "multi_step_median_highest_level": b,
            "grows": (a is not None and b is not None and b > a) or (a is not None and b is None),
        }
    return out
