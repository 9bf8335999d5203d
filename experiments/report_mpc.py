"""The reproduction report's "Closed loop" part (docs/mpc.md): does the paper's claim (local
LTV models are needed; global surrogates fail) survive replanning? One section per system,
each with the verdict its ``mpc`` run reached by the rule of mjx_surrogate/analysis/closed_loop.py,
the measured cause, the side-by-side table, the figures, a still of the episodes' video and
a link to it."""

from __future__ import annotations

import os
from typing import Callable

from experiments.report_rules import RULES
from mjx_surrogate.runs.results import read_json
from mjx_surrogate.systems.plant import parse_plant, plant_slug

MPC = (
    ("pendulum_mpc", "Pendulum swing-up"),
    ("cartpole_mpc", "Cartpole swing-up"),
    (
        "lorenz_mpc",
        "Lorenz system: SINDy-MPC's published task and training length (Kaiser, Kutz, Brunton, "
        "Proc. R. Soc. A 474: 20180335, 2018)",
    ),
    ("gym_inverted_pendulum_mpc", "gymnasium's inverted pendulum, a model we did not write"),
)


def _load(folder: str | None) -> dict:
    return read_json(os.path.join(folder, "metrics.json")) if folder else {}


def _table(text: str) -> str:
    """mpc_table.md without its verdict paragraph (the section states it)."""
    at = text.find("Control period")
    return text[at:] if at >= 0 else text


def closed_loop_sections(L: list, folders: dict, fig: Callable, section: Callable, read: Callable) -> None:
    """Append the part to L (helpers as :func:`experiments.report.render`'s)."""
    from mjx_surrogate.analysis.closed_loop import MATCH_TOL, WORKS_FACTOR

    L += [
        "## Beyond the paper: closed loop",
        "",
        "Every controller replans from the measured state of the black box at every control step "
        "(D2C-MPC, the exact oracle's MPC, SINDy- and MLP-MPC, predictive sampling, MPPI and CEM at "
        "D2C-MPC's budget of black-box calls, and where a preset gives them their own settings, "
        "at those too) or tracks the offline optimum (TVLQR), on the model "
        "and on plants that differ from it, under process noise (docs/mpc.md). Rule: a condition is judged "
        f"where D2C-MPC's own closed loop works (finite median cost at most {WORKS_FACTOR:g}x the "
        "offline optimum's); there a global surrogate's MPC *matches* D2C-MPC when its median "
        f"closed-loop cost is within {100 * MATCH_TOL:g} % of D2C-MPC's and it reaches the goal as "
        "often; the claim **held** where no surrogate matches in any judged condition, **did not "
        "hold** where one matches in every one, held **in part** otherwise, and is **inconclusive** "
        "where no condition is judged.",
        "",
    ]
    verdicts = {}
    for name, title in MPC:
        m = _load(folders.get(name))
        v = m.get("mpc_verdict") or {}
        verdicts[name] = v.get("verdict", "not measured")
        plants = dict.fromkeys(plant_slug(parse_plant(c["plant"])) for c in m.get("mpc_conditions", []))
        figs = [fig(name, f"mpc_cost_vs_noise_{p}.png") for p in plants]
        figs += [fig(name, n) for n in ("mpc_cost_vs_calls.png", "mpc_trajectories.png")]
        video = (m.get("videos") or {}).get("mpc_episodes.mp4") or {}
        if video.get("status") == "written":
            figs.append(fig(name, video.get("still", "")))
            clip = fig(name, "mpc_episodes.mp4")
            order = ", ".join(m.get("mpc_video_order", []))
            link = (
                f" Video of one episode per controller, left to right ({order}): [{name}]({clip})."
                if clip
                else ""
            )
        else:
            link = ""
        text = (
            (f"{v.get('text', 'no mpc run')} {v.get('cause', '')}".strip() + link)
            + "\n\n"
            + _table(read(folders.get(name), "mpc_table.md"))
        )
        section(
            L,
            title,
            "(The paper judges global surrogates in open loop; does feedback change the verdict?)",
            figs,
            text,
            f"**{verdicts[name]}**",
            RULES["closed_loop"].note(),
        )
    counts = {}
    for name, v in verdicts.items():
        counts.setdefault(v, []).append(name)
    L += [
        "**Across the systems:** " + "; ".join(f"{v} on {', '.join(n)}" for v, n in counts.items()) + ".",
        "",
    ]
