"""Experiment kind "horizon" (beyond the paper): how the error of LTV models identified from
perturbed rollouts grows with the rollout's length, open loop (the paper's scheme) against
closed loop under the optimum's gains (mjx_surrogate/analysis/horizon.py; Pfrommer et al., ICML 2023).

Stages: ``optimum`` (the task's D2C optimum and gains), ``reference`` (the oracle's
Jacobians along it, ``experiment.oracle``), then ``levels/<level>``: data.n_traj rollouts
with control noise level x U_max and start offsets level x the std of each state along
the optimum, identified per step open and closed loop; then ``horizon.png``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from mjx_surrogate.analysis import horizon
from mjx_surrogate.control.d2c import exact_linearize
from mjx_surrogate.runs import pipeline, plots
from mjx_surrogate.runs.resolution import Resolved
from mjx_surrogate.runs.results import Run


def _quarter_median(v: np.ndarray, last: bool) -> float | None:
    q = max(1, len(v) // 4)
    part = v[-q:] if last else v[:q]
    return float(np.nanmedian(part)) if np.isfinite(part).any() else None


def run(res: Resolved, record: Run, key: jax.Array) -> str:
    cfg, system, task = res
    k_opt, k_ref, k_roll = jax.random.split(key, 3)
    record.add_arrays({"x0": task.x0})
    m_opt, a_opt = record.stage("optimum", pipeline.optimum_stage(res, k_opt))
    record.set("optimum", m_opt)
    if m_opt["cost"] is None:
        return "diverged"
    X, U, K = (jnp.asarray(a_opt[k]) for k in ("X_star", "U_star", "K_star"))

    def reference():
        A, B = exact_linearize(system, cfg.experiment.oracle)(X, U, K, k_ref)
        return {"oracle": cfg.experiment.oracle}, {"A_ref": A, "B_ref": B}

    _, ref = record.stage("reference", reference)
    A_ref, B_ref = jnp.asarray(ref["A_ref"]), jnp.asarray(ref["B_ref"])
    u_scale = jnp.asarray(a_opt["u_max"])
    x_std = jnp.std(X, axis=0)
    x_scale = jnp.maximum(x_std, 0.1 * jnp.mean(x_std))  # every coordinate excited at t = 0

    errors, cl_errors, spreads, per_level = {}, {}, {}, {}
    for i, level in enumerate(cfg.data.levels):
        perturbation = (jax.random.fold_in(k_roll, i), level * x_scale, level * u_scale)
        m, arrays = record.stage(
            f"levels/{level:g}", lambda p=perturbation, lv=level: _level(res, X, U, K, A_ref, B_ref, lv, *p)
        )
        per_level[f"{level:g}"] = m
        for j, mode in enumerate(("open loop", "closed loop")):
            errors[f"{mode}, {100 * level:g}% U_max"] = arrays[f"errors_{level:g}"][j]
            cl_errors[f"{mode}, {100 * level:g}% U_max"] = arrays[f"cl_errors_{level:g}"][j]
            spreads[f"{mode}, {100 * level:g}% U_max"] = arrays[f"spreads_{level:g}"][j]
    record.set("levels", per_level)
    record.set("finding", {lv: _finding(m) for lv, m in per_level.items()})
    t = np.arange(task.T + 1)
    record.figure(
        "horizon.png",
        lambda: plots.horizon_errors(
            t,
            errors,
            cl_errors,
            spreads,
            f"{system.name}: LTV identified from {cfg.data.n_traj} rollouts of length t, "
            "open loop vs under the optimum's gains",
        ),
    )
    return m_opt["status"]


def _level(res: Resolved, X, U, K, A_ref, B_ref, level: float, key, sigma_x, sigma_u) -> tuple[dict, dict]:
    """One perturbation level: the errors of the models identified from open-loop and
    closed-loop rollouts of every length, and the rollouts' spread."""
    cfg, system, task = res
    out = horizon.identification_errors(
        system, X, U, K, A_ref, B_ref, key, cfg.data.n_traj, sigma_x, sigma_u, task.u_min, task.u_max
    )
    e, ec, s = (np.asarray(a) for a in (out.error, out.closed_loop_error, out.spread))
    m = {}
    for j, mode in enumerate(("open_loop", "closed_loop")):
        first, last = _quarter_median(e[j], False), _quarter_median(e[j], True)
        m[mode] = {
            "error_first_quarter": first,
            "error_last_quarter": last,
            "growth": last / first if first and last is not None else None,
            "A_plus_BK_error_last_quarter": _quarter_median(ec[j], True),
            "spread_first": float(s[j, 0]) if np.isfinite(s[j, 0]) else None,
            "spread_last": float(s[j, -1]) if np.isfinite(s[j, -1]) else None,
        }
    return m, {f"errors_{level:g}": e, f"cl_errors_{level:g}": ec, f"spreads_{level:g}": s}


def _finding(m: dict) -> dict:
    """Whether the closed-loop model's error over the last quarter is below the open loop's."""
    closed, opened = m["closed_loop"]["error_last_quarter"], m["open_loop"]["error_last_quarter"]
    return {
        "closed_loop_below_open_loop_at_the_end": closed is not None and (opened is None or closed < opened)
    }
