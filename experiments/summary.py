"""What a run says when it ends: the summary screen and its one-line form, from the run's
metrics (printed by ``experiments.run``, shown at the top of its ``report.html``)."""

from __future__ import annotations


def summary_screen(metrics: dict, path: str) -> str:
    """The end-of-run summary: one line of status and costs, then per solve its cost,
    verdict, goal test, iterations and time."""
    lines = [summary_line(metrics, path)]
    for key in ("d2c", "optimum", "exact"):
        m = metrics.get(key)
        if not isinstance(m, dict) or "status" not in m:
            continue
        goal = m.get("goal") or {}
        reached = {True: "goal reached", False: "goal NOT reached"}.get(goal.get("reached"), "")
        t = m.get("run_s", m.get("wall_s"))
        lines.append(
            f"  {key:8s} {m['status']:10s} cost {m.get('cost')} ({m.get('iterations')} iterations"
            + (f", {t:.2f} s" if isinstance(t, (int, float)) else "")
            + (f", compile {m['compile_s']:.1f} s" if isinstance(m.get("compile_s"), (int, float)) else "")
            + f") {reached}"
            + (f"; goal cost {goal.get('goal_cost_start')} -> {goal.get('goal_cost_final')}" if goal else "")
        )
        if m.get("hint"):
            lines.append(f"           hint: {m['hint']}")
    gains = (metrics.get("feedback") or {}).get("gains")
    if gains:
        lines.append(f"  feedback gains: {gains}")
    times = time_line(metrics)
    if times:
        lines.append(times)
    return "\n".join(lines)


def time_line(metrics: dict) -> str:
    """Where the wall time went: each stage (compiles included), then the rest (loading,
    checks, the model and figure files)."""
    stages: dict = {}
    for k, v in (metrics.get("stages") or {}).items():
        if isinstance(v.get("wall_s"), float):  # mpc/<controller>/<condition>: one sum per controller
            group = "/".join(k.split("/")[:2])
            stages[group] = stages.get(group, 0.0) + v["wall_s"]
    total = metrics.get("wall_time_s")
    if not stages or not isinstance(total, (int, float)):
        return ""
    parts = [f"{k} {v:.1f} s" for k, v in stages.items()]
    parts.append(f"setup and files {max(total - sum(stages.values()), 0.0):.1f} s")
    return f"  time: {', '.join(parts)} (total {total:.1f} s)"


def summary_line(metrics: dict, path: str) -> str:
    """One line: status, the main costs, the time, the folder."""
    parts = [f"[{metrics.get('status')}]"]
    for key in ("d2c", "optimum", "exact"):
        m = metrics.get(key)
        if isinstance(m, dict) and "cost" in m:
            parts.append(f"{key} cost {m['cost']}")
    if "d2c_vs_exact_relative_gap" in metrics:
        parts.append(f"gap {100 * metrics['d2c_vs_exact_relative_gap']:.3g} %")
    if metrics.get("error"):
        parts.append(f"({metrics['error'].splitlines()[0][:200]})")
    parts.append(f"{metrics.get('wall_time_s', 0):.1f} s; run folder: {path}")
    return " ".join(parts)
