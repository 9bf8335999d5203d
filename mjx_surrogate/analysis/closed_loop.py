"""What an ``mpc`` run says (experiment kind ``mpc``, docs/mpc.md): its side-by-side
table, and its closed-loop verdict by an explicit rule: does the paper's claim (local LTV
models are needed; global surrogates fail, Sec. 5) survive replanning?

Rule, per condition (plant, process noise) of the run's side-by-side rows:
- a condition is *judged* when D2C-MPC's own closed loop works there: its median cost is
  finite and at most ``WORKS_FACTOR`` times the offline optimum's (the task's cost over
  the same steps); elsewhere the local approach shows nothing to be needed for;
- a global surrogate's MPC (SINDy, MLP) *matches* D2C-MPC when its median closed-loop cost
  is within ``MATCH_TOL`` of D2C-MPC's and it reaches the goal in at least as many episodes;
- over the judged conditions, the claim **held** when no surrogate matches in any, **did
  not hold** when one surrogate matches in every one, and held **in part** otherwise; it is
  **inconclusive** when no condition is judged.
The cause is measured beside it: each surrogate's one-step prediction error along its own
closed loop on the first plant at the least noise (``closed_loop_one_step_error``,
relative to the optimum's RMS state).
"""

from __future__ import annotations

import math

import numpy as np

MATCH_TOL = 0.10
WORKS_FACTOR = 10.0
SURROGATE_PREFIXES = ("SINDy", "MLP")
D2C = "D2C-MPC"


def _cost(r: dict) -> float:
    c = r.get("cost_median")
    return math.inf if c is None or not math.isfinite(c) else float(c)


def _where(c: dict) -> str:
    return f"plant {c['plant']}, noise {c['process_noise']:g}"


def _condition(at: dict, surrogates: list[str], offline_cost: float | None) -> dict:
    d = at[D2C]
    base = _cost(d)
    ratios = {n: _cost(at[n]) / base if math.isfinite(base) else math.nan for n in surrogates if n in at}
    matches = [
        n for n, q in ratios.items() if q <= 1 + MATCH_TOL and at[n]["goal_reached"] >= d["goal_reached"]
    ]
    works = math.isfinite(base) and (offline_cost is None or base <= WORKS_FACTOR * offline_cost)
    return {
        "plant": d["plant"],
        "process_noise": d["process_noise"],
        "d2c_cost": base if math.isfinite(base) else None,
        "d2c_goal_reached": d["goal_reached"],
        "judged": works,
        "ratios": {n: (None if not math.isfinite(q) else q) for n, q in ratios.items()},
        "matches": matches,
    }


def closed_loop_verdict(rows: list[dict], offline_cost: float | None = None) -> dict:
    """{verdict: held | did not hold | held in part | inconclusive | not measured, text,
    conditions: [{plant, process_noise, d2c_cost, d2c_goal_reached, judged,
    ratios {label: cost / D2C-MPC's}, matches [labels]}], match_tol, works_factor}.
    offline_cost: the offline optimum's cost over the episodes' steps (None: not checked)."""
    surrogates = list(
        dict.fromkeys(r["controller"] for r in rows if r["controller"].startswith(SURROGATE_PREFIXES))
    )
    if not surrogates or not any(r["controller"] == D2C for r in rows):
        missing = "the run had no D2C-MPC or no global surrogate"
        return {"verdict": "not measured", "text": missing, "conditions": []}
    per = []
    for key in dict.fromkeys((r["plant"], r["process_noise"]) for r in rows):
        at = {r["controller"]: r for r in rows if (r["plant"], r["process_noise"]) == key}
        if D2C in at:
            per.append(_condition(at, surrogates, offline_cost))
    judged = [c for c in per if c["judged"]]
    out = [c for c in per if not c["judged"]]
    always = [n for n in surrogates if judged and all(n in c["matches"] for c in judged)]
    some = [c for c in judged if c["matches"]]
    tol = f"{100 * MATCH_TOL:g} %"
    if not judged:
        verdict, text = "inconclusive", "D2C-MPC itself failed in every condition."
    elif always:
        verdict = "did not hold"
        text = f"{', '.join(always)} control{'s' if len(always) == 1 else ''} within {tol} of D2C-MPC's cost"
        text += " in every condition judged."
    elif not some:
        verdict = "held"
        text = f"every global surrogate's MPC costs over {tol} more than D2C-MPC in every condition judged."
    else:
        verdict = "held in part"
        text = (
            "a surrogate matches D2C-MPC at "
            + "; ".join(f"{_where(c)} ({', '.join(c['matches'])})" for c in some)
            + "."
        )
    if out:
        text += (
            " Not judged (D2C-MPC diverged or cost over "
            f"{WORKS_FACTOR:g}x the offline optimum's): " + "; ".join(_where(c) for c in out) + "."
        )
    best = [
        f"{_where(c)}: best surrogate {min(c['ratios'], key=lambda n: c['ratios'][n] or math.inf)} "
        f"x{min((q for q in c['ratios'].values() if q is not None), default=math.inf):.3g}"
        for c in judged
    ]
    if best:
        text += " Cost relative to D2C-MPC's, " + "; ".join(best) + "."
    return {
        "verdict": verdict,
        "text": text,
        "conditions": per,
        "match_tol": MATCH_TOL,
        "works_factor": WORKS_FACTOR,
    }


def cause_text(rows: list[dict]) -> str:
    """The surrogates' one-step prediction errors along their own closed loops, as measured."""
    errs = {
        r["controller"]: r["closed_loop_one_step_error"]
        for r in rows
        if r.get("closed_loop_one_step_error") is not None
    }
    if not errs:
        return ""
    plant = next(r["plant"] for r in rows if r.get("closed_loop_one_step_error") is not None)
    return (
        f"One-step prediction error along each surrogate's own closed loop (plant {plant}, "
        "least noise; median over steps, relative to the optimum's RMS state): "
        + ", ".join(f"{n} {100 * e:.3g} %" for n, e in errs.items())
        + "."
    )


def in_goal_from(passes) -> int | None:
    """The first step n from which every state passes the goal test (``passes`` [N+1],
    bool): the episode entered the goal then and stayed; None if its last state fails."""
    passes = np.asarray(passes, bool)
    if not passes[-1]:
        return None
    failed = np.flatnonzero(~passes)
    return int(failed[-1] + 1) if len(failed) else 0


def _entered(r: dict) -> str:
    """'median (latest)' of the episodes' in-goal-from times, '-' where one never stays."""
    t = r.get("in_goal_from_s")
    if not t or any(v is None for v in t):
        held = 0 if not t else sum(v is not None for v in t)
        return "-" if not t else f"- ({held} of {len(t)} stay)"
    return f"{np.median(t):.3g} ({max(t):.3g})"


def table(rows: list[dict], dt: float, verdict: dict | None = None, horizon: str = "") -> str:
    """The side-by-side table (Markdown), one block per condition, after the verdict;
    ``horizon``: where the plans end, a sentence."""
    f = lambda v: "-" if v is None else f"{v:.4g}"  # noqa: E731
    points = any("point_error_median" in r for r in rows)  # a task with point goals
    out = []
    for p, w in dict.fromkeys((r["plant"], r["process_noise"]) for r in rows):
        out += [
            f"\n### Plant {p}, process noise {w:g}\n",
            "| controller | closed-loop cost (median) | min - max | goal reached | in goal from, s "
            "(latest) | black-box steps per control step | iterations per replan | ms per control "
            "step | real-time factor |" + (" point error over the 2nd half, m (median) |" if points else ""),
            "|---|---|---|---|---|---|---|---|---|" + ("---|" if points else ""),
        ]
        for r in rows:
            if (r["plant"], r["process_noise"]) != (p, w):
                continue
            c = [v for v in r["costs"] if v is not None]
            spread = (
                f"{min(c):.4g} - {max(c):.4g}"
                if len(c) == len(r["costs"])
                else f"{len(r['costs']) - len(c)} diverged"
            )
            out.append(
                f"| {r['controller']} | {f(r['cost_median'])} | {spread} | "
                f"{100 * r['goal_reached']:.0f} % | {_entered(r)} | "
                f"{f(r['black_box_steps_per_control_step'])} | {f(r['iterations_per_replan'])} | "
                f"{1e3 * r['compute_per_step_s']:.3g} | {r['real_time_factor']:.3g} |"
                + (f" {f(r.get('point_error_median'))} |" if points else "")
            )
    head = ""
    if verdict:
        head = (
            f"**Closed loop, the paper's claim: {verdict['verdict']}** "
            "(rule: mjx_surrogate/analysis/closed_loop.py). "
            f"{verdict['text']} {verdict.get('cause', '')}\n\n"
        )
    return (
        head + f"Control period {dt:g} s; compute per control step: a batch's wall time over its "
        "episodes' steps." + (f" Horizon: {horizon}." if horizon else "") + "\n" + "\n".join(out) + "\n"
    )
