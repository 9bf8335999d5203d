"""What an ``mpc`` run says: its side-by-side table, and its closed-loop verdict by an
explicit rule: does the paper's claim (local LTV models are needed; global surrogates
fail, Sec. 5) survive replanning?

Rule, per condition (plant, process noise) of the run's side-by-side rows:
- a global surrogate's MPC (SINDy, MLP) *matches* D2C-MPC when its median closed-loop cost
  is within ``MATCH_TOL`` of D2C-MPC's and it reaches the goal in at least as many episodes;
- the claim **held** when no surrogate matches in any condition, **did not hold** when one
  surrogate matches in every condition, and held **in part** otherwise;
- the test is **inconclusive** when D2C-MPC's own closed loop diverged (non-finite cost) or,
  where the offline optimum reaches the goal and the episodes are as long as the task,
  D2C-MPC reached it in no episode of a condition: the local approach then shows nothing
  to be needed for.
The cause is measured beside it: each surrogate's one-step prediction error along its own
closed loop on the first plant at the least noise (``closed_loop_one_step_error``,
relative to the optimum's RMS state).
"""

from __future__ import annotations

import math

MATCH_TOL = 0.10
SURROGATE_PREFIXES = ("SINDy", "MLP")
D2C = "D2C-MPC"


def _cost(r: dict) -> float:
    c = r.get("cost_median")
    return math.inf if c is None or not math.isfinite(c) else float(c)


def closed_loop_verdict(rows: list[dict], offline_goal_reached: bool = True) -> dict:
    """{verdict: held | did not hold | held in part | inconclusive | not measured, text,
    conditions: [{plant_mass_scale, process_noise, d2c_cost, ratios {label: cost / D2C's},
    matches [labels]}]}."""
    conditions = list(dict.fromkeys((r["plant_mass_scale"], r["process_noise"]) for r in rows))
    per, surrogates = (
        [],
        list(dict.fromkeys(r["controller"] for r in rows if r["controller"].startswith(SURROGATE_PREFIXES))),
    )
    if not surrogates or not any(r["controller"] == D2C for r in rows):
        missing = "the run had no D2C-MPC or no global surrogate"
        return {"verdict": "not measured", "text": missing, "conditions": []}
    for s, w in conditions:
        at = {r["controller"]: r for r in rows if (r["plant_mass_scale"], r["process_noise"]) == (s, w)}
        d = at.get(D2C)
        if d is None:
            continue
        base = _cost(d)
        ratios = {n: _cost(at[n]) / base if math.isfinite(base) else math.nan for n in surrogates if n in at}
        matches = [
            n for n, q in ratios.items() if q <= 1 + MATCH_TOL and at[n]["goal_reached"] >= d["goal_reached"]
        ]
        per.append(
            {
                "plant_mass_scale": s,
                "process_noise": w,
                "d2c_cost": None if not math.isfinite(_cost(d)) else _cost(d),
                "d2c_goal_reached": d["goal_reached"],
                "ratios": {n: (None if not math.isfinite(q) else q) for n, q in ratios.items()},
                "matches": matches,
            }
        )
    where = lambda c: f"masses x{c['plant_mass_scale']:g}, noise {c['process_noise']:g}"  # noqa: E731
    broken = [
        c for c in per if c["d2c_cost"] is None or (offline_goal_reached and c["d2c_goal_reached"] == 0)
    ]
    if broken:
        verdict = "inconclusive"
        text = (
            "D2C-MPC itself diverged or never reached the goal at "
            + "; ".join(where(c) for c in broken)
            + ": the comparison shows nothing the local approach is needed for."
        )
    else:
        always = [n for n in surrogates if all(n in c["matches"] for c in per)]
        some = [c for c in per if c["matches"]]
        if always:
            verdict = "did not hold"
            text = (
                f"{', '.join(always)} controls within {100 * MATCH_TOL:g} % of D2C-MPC's cost "
                "in every condition."
            )
        elif not some:
            verdict = "held"
            text = (
                f"every global surrogate's MPC costs over {100 * MATCH_TOL:g} % more than D2C-MPC "
                "in every condition."
            )
        else:
            verdict = "held in part"
            text = "a surrogate matches D2C-MPC at " + "; ".join(
                f"{where(c)} ({', '.join(c['matches'])})" for c in some
            )
    best = [
        f"{where(c)}: best surrogate {min(c['ratios'], key=lambda n: c['ratios'][n] or math.inf)} "
        f"x{min((q for q in c['ratios'].values() if q is not None), default=math.inf):.3g}"
        for c in per
    ]
    text += " Cost relative to D2C-MPC's, " + "; ".join(best) + "."
    return {"verdict": verdict, "text": text, "conditions": per, "match_tol": MATCH_TOL}


def cause_text(rows: list[dict]) -> str:
    """The surrogates' one-step prediction errors along their own closed loops, as measured."""
    errs = {
        r["controller"]: r["closed_loop_one_step_error"]
        for r in rows
        if r.get("closed_loop_one_step_error") is not None
    }
    if not errs:
        return ""
    plant = next(r["plant_mass_scale"] for r in rows if r.get("closed_loop_one_step_error") is not None)
    return (
        f"One-step prediction error along each surrogate's own closed loop (plant masses "
        f"x{plant:g}, least noise; median over steps, relative to the optimum's RMS state): "
        + ", ".join(f"{n} {100 * e:.3g} %" for n, e in errs.items())
        + "."
    )


def table(rows: list[dict], dt: float, verdict: dict | None = None) -> str:
    """The side-by-side table (Markdown), one block per condition, after the verdict."""
    f = lambda v: "-" if v is None else f"{v:.4g}"  # noqa: E731
    out = []
    for s, w in dict.fromkeys((r["plant_mass_scale"], r["process_noise"]) for r in rows):
        out += [
            f"\n### Plant masses x{s:g}, process noise {w:g}\n",
            "| controller | closed-loop cost (median) | min - max | goal reached | black-box steps "
            "per control step | iterations per replan | ms per control step | real-time factor |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for r in rows:
            if (r["plant_mass_scale"], r["process_noise"]) != (s, w):
                continue
            c = [v for v in r["costs"] if v is not None]
            spread = (
                f"{min(c):.4g} - {max(c):.4g}"
                if len(c) == len(r["costs"])
                else f"{len(r['costs']) - len(c)} diverged"
            )
            out.append(
                f"| {r['controller']} | {f(r['cost_median'])} | {spread} | {100 * r['goal_reached']:.0f} % | "
                f"{f(r['black_box_steps_per_control_step'])} | {f(r['iterations_per_replan'])} | "
                f"{1e3 * r['compute_per_step_s']:.3g} | {r['real_time_factor']:.3g} |"
            )
    head = ""
    if verdict:
        head = (
            f"**Closed loop, the paper's claim: {verdict['verdict']}** (rule: experiments/mpc_report.py). "
            f"{verdict['text']} {verdict.get('cause', '')}\n\n"
        )
    return (
        head + f"Control period {dt:g} s; compute per control step: a batch's wall time over its "
        "episodes' steps.\n" + "\n".join(out) + "\n"
    )
