"""The reproduction report's "Beyond the paper: a PDE" part (docs/pde.md): RO-D2C on the
Burgers equation against the jacfwd oracle, and the paper's prediction study on it."""

from __future__ import annotations

import os
from typing import Callable

from experiments.report_rules import RULES
from mjx_surrogate.runs.results import read_json

GAP_TOL = RULES["ro_d2c"].value("gap")  # RO-D2C "reaches the oracle": within this of its cost


def _load(folder: str | None) -> dict:
    return read_json(os.path.join(folder, "metrics.json")) if folder else {}


def _global_models(res: dict) -> list[str]:
    return [n for n in res if not n.startswith("_") and not n.startswith("LTV")]


def _local_over_global(at_level: dict, glob: list, local: list) -> list[float]:
    """Per data set of one level (``data.n_seeds``; the medians where the run has one): the
    best local model's multi-step error over the best global model's (a diverged model's
    error is inf; below 1: the local model predicts better)."""
    inf = float("inf")

    def errors(name: str) -> list:
        v = at_level[name]
        return v["per_seed"]["multi_step_median"] if "per_seed" in v else [v["multi_step_median"]]

    def best(names: list) -> list[float]:
        return [min(inf if e is None else e for e in col) for col in zip(*(errors(n) for n in names))]

    def ratio(a: float, b: float) -> float:
        if a == inf or b == inf:
            return inf if a == inf else 0.0
        return a / b if b > 0 else (1.0 if a == 0 else inf)

    return [ratio(a, b) for a, b in zip(best(local), best(glob))]


def pde_sections(L: list, folders: dict, fig: Callable, _section, _verdict, _f, _read) -> None:
    """Append the part's two sections to L (helpers as :func:`experiments.report.render`'s)."""
    L += ["## Beyond the paper: a PDE", ""]
    name = "burgers_ro_d2c"
    m = _load(folders.get(name))
    cfg = read_json(os.path.join(folders[name], "config.json")) if folders.get(name) else {}
    d, e = m.get("d2c", {}), m.get("exact", {})
    gap = m.get("d2c_vs_exact_relative_gap")
    ranks = (m.get("ltv_relative_error") or {}).get("basis_rank") or [0]
    measured = (
        f"RO-D2C (`sysid.scheme reduced`, {cfg.get('sysid', {}).get('n_samples')} "
        f"snapshot rollouts) on `{cfg.get('system', {}).get('name')}`: "
        f"**{d.get('status', 'missing')}** after {d.get('iterations')} iterations, "
        f"cost {_f(d.get('cost'), 8)} against the jacfwd oracle's {_f(e.get('cost'), 8)} "
        f"(gap {_f(None if gap is None else 100 * gap)} %), "
        f"{d.get('simulated_steps')} simulated control steps, {_f(d.get('run_s'))} s against the oracle's "
        f"{_f(e.get('run_s'))} s (compile apart); basis rank at most {max(ranks)}. Full-order D2C at "
        "1024 cells: `python benchmarks/pde.py` (docs/performance.md)."
    )
    held = None if gap is None else d.get("status") == "converged" and abs(gap) <= GAP_TOL
    _section(
        L,
        "Reduced-order D2C on the viscous Burgers equation",
        "(The authors' RO-ILQR, arXiv 2501.06635, on an equation they tested; this project's discretisation)",
        [fig(name, f) for f in ("cost_history.png", "cost_vs_simulations.png")],
        measured,
        _verdict(held),
        RULES["ro_d2c"].note(),
    )
    name = "burgers_predict"
    p = _load(folders.get(name))
    res = p.get("results") or {}
    if not res:
        held, text = None, "no results"
    else:
        lo = f"{p['levels'][0]:g}"
        glob = _global_models(res[lo])
        best = min(glob, key=lambda n: res[lo][n]["multi_step_median"] or float("inf"))
        local = {n: res[lo][n]["multi_step_median"] for n in res[lo] if n.startswith("LTV")}
        best_local = min(local, key=lambda n: local[n] if local[n] is not None else float("inf"))
        ratios = _local_over_global(res[lo], glob, list(local))
        wins = [r < 1 for r in ratios]
        held = all(wins)
        text = (
            f"At {100 * p['levels'][0]:g} % U_max the best global model is {best} "
            f"({_f(res[lo][best]['multi_step_median'])}), the best local one {best_local} "
            f"({_f(local[best_local])}); the full-order LTV model: {_f(local.get('LTV'))} (its per-t "
            "regression is rank-deficient: trajectories from one start span at most nu t directions at "
            "step t). "
            + (
                f"Judged on each of the {len(wins)} data sets of the level (`data.n_seeds`; the errors "
                f"above are medians over them): the best local model's error over the best global "
                f"model's ranges {_f(min(ratios))}-{_f(max(ratios))}; the local model is the better on "
                f"{sum(wins)} of {len(wins)}."
                if len(wins) > 1
                else "Judged on one data set per level (`data.n_seeds` 1): no interval."
            )
            + "\n\n"
            + _read(folders.get(name), "rmse_table.md")
        )
    _section(
        L,
        "The paper's prediction study on the Burgers equation",
        "(The paper's Fig. LTV study carried to a PDE; docs/pde.md)",
        [fig(name, f) for f in ("multi_step_median_vs_level.png", "locality.png")],
        text,
        _verdict(held),
        RULES["pde_prediction"].note(),
    )
