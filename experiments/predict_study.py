"""Experiment kind "predict": the paper's prediction experiments.

1. Stage ``optimum``: the task's optimum (X*, U*) by D2C on the black box.
2. Stage ``results/<level>`` for each perturbation level: ``data.n_seeds`` data sets of
   perturbed trajectories around it, each split train : test by trajectory; every
   registered surrogate kind of ``surrogate.kinds`` (the seeds at once where the kind can)
   and the local LTV model fitted on each training set; one-step and open-loop multi-step
   predictions on each test set. A model's metrics are the medians over the data sets,
   with each data set's under ``per_seed``; the figures show the first data set's.
"""

from __future__ import annotations

import time
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from mjx_surrogate import progress
from mjx_surrogate.analysis import locality
from mjx_surrogate.analysis.evaluation import error_grows, prediction_errors
from mjx_surrogate.identification import data, step_models, sysid
from mjx_surrogate.runs import pipeline, plots
from mjx_surrogate.runs.resolution import Resolved
from mjx_surrogate.runs.results import Run
from mjx_surrogate.surrogates import FitContext, fit_all_seeds

PER_SEED = ("one_step_rmse", "multi_step_median", "multi_step_rmse", "diverged")


def level_stage(res: Resolved, X_star, U_star, level: float, i: int, keys: list):
    """A stage: ``len(keys)`` data sets at one level (one per key; the first key's data set
    is the single-seed study's), every model fitted and evaluated on each."""
    cfg, system, task = res
    dc = cfg.data

    def compute():
        n_steps = len(cfg.surrogate.kinds) + 3
        with progress.steps(f"predict {100 * level:g}% U_max", n_steps, cfg.experiment.progress) as meter:
            return _compute(meter)

    def _compute(meter):
        splits = [jax.random.split(k, 3) for k in keys]
        meter.advance(f"sample {len(keys)} x {dc.n_traj} trajectories")
        t0 = time.perf_counter()
        lim = (task.u_min, task.u_max)
        sample = partial(data.sample, system, X_star, U_star)
        sets = [sample(k[0], dc.n_traj, level, dc.x0_sigma, *lim) for k in splits]
        sets = jax.block_until_ready(sets)
        t_data = time.perf_counter() - t0
        parts = [data.split(ds, k[1], dc.test_fraction) for ds, k in zip(sets, splits)]
        fitted = fit_all_seeds(
            FitContext(cfg, system, task.T),
            [data.transitions(tr) for tr, _ in parts],
            [data.transitions(te) for _, te in parts],
            [k[2] for k in splits],
            meter,
        )
        meter.advance("fit LTV")
        steps, info = [], []
        for (train, _), fs in zip(parts, fitted):
            st = {name: step_models.as_pytree(f.model) for name, f in fs.items()}
            inf = {name: f.info for name, f in fs.items()}
            t0 = time.perf_counter()
            st["LTV"] = step_models.fit_ltv(train, X_star, U_star).as_pytree()
            inf["LTV"] = {"fit_s": time.perf_counter() - t0}
            if cfg.surrogate.reduced_ltv_tol is not None:
                t0 = time.perf_counter()
                tol = cfg.surrogate.reduced_ltv_tol
                st["LTV reduced"] = step_models.fit_reduced_ltv(train, X_star, U_star, tol).as_pytree()
                inf["LTV reduced"] = {"fit_s": time.perf_counter() - t0}
            steps.append(st)
            info.append(inf)
        meter.advance("prediction errors")
        arrays = {f"level{i}_test_X": data.finite_trajectories(parts[0][1]).X[0]}
        seeds = [{} for _ in keys]
        for s, ((_, test), st) in enumerate(zip(parts, steps)):
            for name, step_t in st.items():
                seeds[s][name], pred = prediction_errors(step_t, test)
                if s == 0:
                    arrays[f"level{i}_pred_{name.replace(' ', '_')}"] = pred[0]
        per_model = {name: {**_over_seeds([m[name] for m in seeds]), **info[0][name]} for name in steps[0]}
        for name, f in fitted[0].items():
            for k, v in f.arrays.items():
                arrays[f"{name.replace(' ', '_').lower()}_{k}_{level:g}"] = v
        spreads = [float(locality.relative_spread(ds.X, X_star)) for ds in sets]
        per_model["_data"] = {
            "sample_s": t_data,
            "n_train": int(parts[0][0].X.shape[0]),
            "n_test": int(parts[0][1].X.shape[0]),
            "n_seeds": len(keys),
            "relative_spread": float(np.median(spreads)),
            "relative_spread_per_seed": spreads,
        }
        return per_model, arrays

    return compute


def _over_seeds(ms: list[dict]) -> dict:
    """A model's metrics over the data sets: each the median (a diverged, None, value counts
    as infinitely large, and a median that is infinite is None), each data set's under
    ``per_seed``."""
    out = {}
    for k in PER_SEED:
        v = [m[k] for m in ms]
        med = float(np.median([np.inf if x is None else x for x in v]))
        out[k] = med if np.isfinite(med) else None
    out["per_seed"] = {k: [m[k] for m in ms] for k in PER_SEED}
    return out


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
        keys = [k] + [jax.random.fold_in(k, s) for s in range(1, dc.n_seeds)]
        stage = level_stage(res, X_star, U_star, level, i, keys)
        per_model, arrays = record.stage(f"results/{level:g}", stage)
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
        ranges = None
        if dc.n_seeds > 1:  # the band: least and largest over the data sets (a diverged one: inf)
            ranges = {
                n: np.asarray(
                    [
                        [
                            f(np.inf if v is None else v for v in clean[f"{lv:g}"][n]["per_seed"][key_])
                            for lv in dc.levels
                        ]
                        for f in (min, max)
                    ]
                )
                for n in names
            }
        title = f"{system.name}: test {label}"
        title += f"\nmedian and range over {dc.n_seeds} data sets" if ranges else ""
        record.figure(
            f"{key_}_vs_level.png",
            lambda: plots.error_vs_level(np.asarray(dc.levels), errs, label, title, ranges),
        )
    over = f" (each the median over {dc.n_seeds} data sets)" if dc.n_seeds > 1 else ""
    record.folder.write_text(
        "rmse_table.md",
        (
            f"**One-step test RMSE{over}**\n\n"
            + _rmse_table(dc.levels, clean, "one_step_rmse")
            + f"\n**Open-loop multi-step test RMSE (median over test trajectories){over}**\n\n"
            + _rmse_table(dc.levels, clean, "multi_step_median")
        ),
    )
    record.set("finding", _finding(dc.levels, clean))
    return m_opt["status"]


def _finding(levels, clean: dict) -> dict:
    """Does each model's error grow from the lowest to the highest level (medians over the
    data sets), and on how many of the data sets does it?"""
    out = {}
    lo, hi = f"{min(levels):g}", f"{max(levels):g}"

    for name in clean[lo]:
        a, b = clean[lo][name]["multi_step_median"], clean[hi][name]["multi_step_median"]
        pa, pb = (clean[lv][name]["per_seed"]["multi_step_median"] for lv in (lo, hi))
        out[name] = {
            "multi_step_median_lowest_level": a,
            "multi_step_median_highest_level": b,
            "grows": error_grows(a, b),
            "grows_on_data_sets": sum(error_grows(x, y) for x, y in zip(pa, pb)),
        }
    return out
