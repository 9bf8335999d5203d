"""The reproduction report: the paper's figures in order, each with its caption (quoted from
the paper), what was measured here, and whether the paper's claim held."""

from __future__ import annotations

import datetime
import os
import shutil

from experiments import report_control, report_ltv, report_mpc, report_pde
from experiments.report_rules import RULES, convergence_claim, mlp_variance_claim, rules_table, theory_claim
from mjx_surrogate.analysis.evaluation import error_grows
from mjx_surrogate.runs.results import read_json, versions


def _load(folder: str | None) -> dict:
    if not folder:
        return {}
    return read_json(os.path.join(folder, "metrics.json"))


def _read(folder: str | None, name: str) -> str:
    p = os.path.join(folder or "", name)
    return open(p).read() if folder and os.path.exists(p) else ""


def _f(v, p=3) -> str:
    if isinstance(v, str):  # a non-finite number as written to JSON ("inf", "nan")
        return v
    return "diverged" if v is None else f"{v:.{p}g}"


def _verdict(ok: bool | None) -> str:
    return {True: "**held**", False: "**did not hold**", None: "**not measured**"}[ok]


def _state_scale(folder: str | None) -> float | None:
    """RMS of the optimal trajectory's states: the scale a prediction error is judged on."""
    import numpy as np

    p = os.path.join(folder or "", "arrays.npz")
    if not folder or not os.path.exists(p):
        return None
    X = np.load(p)["X_star"]
    return float(np.sqrt(np.mean(X**2)))


LOCAL_SPREAD = RULES["prediction"].value("local_spread")  # a data set is local below this spread


def _ltv_over_best(at_level: dict, glob: list) -> float | None:
    """The LTV model's multi-step error over the best global model's at one level (None
    where the LTV model diverged; 0 where every global model did)."""
    ltv = at_level["LTV"]["multi_step_median"]
    best = min((at_level[n]["multi_step_median"] or float("inf")) for n in glob)
    return None if ltv is None else ltv / best


def _seed_views(m: dict) -> list[dict]:
    """A prediction run's results as each of its data sets saw them (``data.n_seeds``;
    the run itself where it has one, or where its metrics predate seeds)."""
    res = m["results"]
    n = next(iter(res.values())).get("_data", {}).get("n_seeds", 1)
    if n == 1:
        return [m]

    def one(v: dict, s: int) -> dict:
        if "per_seed" in v:
            return {**v, **{k: vs[s] for k, vs in v["per_seed"].items()}}
        return {**v, "relative_spread": v["relative_spread_per_seed"][s]}

    return [
        {**m, "results": {lv: {name: one(v, s) for name, v in r.items()} for lv, r in res.items()}}
        for s in range(n)
    ]


def _grows(lo: float | None, hi: float | None) -> bool:
    """A global model's error grows from the lowest to the highest level (or diverges at
    the highest); one that already diverges at the lowest level counts as failing there, as
    the claim says of global models."""
    return lo is None or error_grows(lo, hi)


def _judge_prediction(m: dict, scale: float | None) -> dict:
    """The prediction rule on one data set per level (``m`` one of :func:`_seed_views`)."""
    rule = RULES["prediction"]
    levels = [f"{v:g}" for v in m["levels"]]
    lo, hi = levels[0], levels[-1]
    res = m["results"]
    glob = [n for n in res[lo] if not n.startswith("_") and n != "LTV"]
    grows = {n: _grows(res[lo][n]["multi_step_median"], res[hi][n]["multi_step_median"]) for n in glob}
    ltv_lo = res[lo]["LTV"]["multi_step_median"]
    ratio = _ltv_over_best(res[lo], glob)
    spread = res[lo].get("_data", {}).get("relative_spread")
    if spread is None:  # metrics without a data entry per level
        spread = ((m.get("locality") or {}).get("relative_spread") or {}).get(lo)
    accurate = ltv_lo is not None and scale is not None and ltv_lo <= rule.value("ltv_state_fraction") * scale
    local = spread is not None and spread < LOCAL_SPREAD
    return {
        "held": all(grows.values())
        and accurate
        and ratio is not None
        and ratio <= rule.value("ltv_over_global")
        and local,
        "grows": grows,
        "accurate": accurate,
        "ratio": ratio,
        "local": local,
        "spread": spread,
        "glob": glob,
    }


def _predict_claim(m: dict, scale: float | None = None) -> tuple[bool | None, str]:
    """The prediction claim, judged on each data set of each level: held where it holds on
    every one (the text gives the medians over them)."""
    if not m.get("results"):
        return None, "no results"
    levels = [f"{v:g}" for v in m["levels"]]
    lo, hi = levels[0], levels[-1]
    res = m["results"]
    views = [_judge_prediction(v, scale) for v in _seed_views(m)]
    med = _judge_prediction(m, scale)
    glob = med["glob"]
    ltv_lo = res[lo]["LTV"]["multi_step_median"]
    text = (
        f"Open-loop multi-step test RMSE (median over test trajectories) grows from "
        f"{100 * m['levels'][0]:g} % to {100 * m['levels'][-1]:g} % U_max for: "
        + ", ".join(
            f"{n} {'yes (or diverged)' if all(v['grows'][n] for v in views) else 'no'} "
            f"({_f(res[lo][n]['multi_step_median'])} -> {_f(res[hi][n]['multi_step_median'])})"
            for n in glob
        )
        + f". LTV: {_f(ltv_lo)} -> {_f(res[hi]['LTV']['multi_step_median'])} (a local model: "
        f"it is meant to be accurate near its trajectory, i.e. at the small levels). At "
        f"{100 * m['levels'][0]:g} % the LTV error is {_f(med['ratio'] if ltv_lo else None)}x "
        f"the best global model's (at each level: "
        + ", ".join(f"{_f(_ltv_over_best(res[lv], glob))} at {100 * float(lv):g} %" for lv in levels)
        + ")."
        + _mlp_epochs_text(res, levels)
    )
    if scale is not None and ltv_lo is not None:
        text += (
            f" The LTV error at the lowest level is {_f(ltv_lo / scale)} of the RMS state "
            f"along the optimum ({_f(scale)})."
        )
    if len(views) > 1:
        ratios = [v["ratio"] for v in views if v["ratio"] is not None]
        text += (
            f" Over the {len(views)} data sets of each level (`data.n_seeds`; the errors above are "
            "medians over them, the epochs and the prediction plots the first data set's): at the "
            "lowest level the LTV error over the best global model's "
            + (f"ranges {_f(min(ratios))}-{_f(max(ratios))}" if ratios else "is not finite")
            + f"; the rule holds on {sum(v['held'] for v in views)} of {len(views)}."
        )
    else:
        text += " Judged on one data set per level (`data.n_seeds` 1): no interval."
    loc = m.get("locality") or {}
    spread = loc.get("relative_spread") or {}
    if spread:
        text += (
            " Locality (docs/method.md): median relative spread of the data sets "
            + ", ".join(f"{_f(spread.get(lv))} at {100 * float(lv):g} %" for lv in levels)
            + f"; open-loop gain of the optimum {_f(loc.get('open_loop_gain'))}."
        )
    held = all(v["held"] for v in views)
    if not held:
        text += _prediction_causes(views, res[lo], glob, scale)
    return held, text


def _prediction_causes(views: list[dict], lowest: dict, glob: list, scale: float | None) -> str:
    """Why the prediction claim did not hold: each part of the rule that failed, on how
    many of the data sets."""
    n, causes = len(views), []
    of = lambda k: f"{k} of {n} data sets" if n > 1 else "its data set"  # noqa: E731
    for name in glob:
        k = sum(not v["grows"][name] for v in views)
        if k:
            e = lowest[name]["multi_step_median"]
            above = scale is not None and e is not None and e > scale
            causes.append(
                f"{name}'s error does not grow on {of(k)}"
                + (
                    f" (its median error at the lowest level is already {_f(e / scale)}x the RMS "
                    "state: its open-loop predictions blow up there)"
                    if above
                    else ""
                )
            )
    k = sum(v["ratio"] is None or v["ratio"] > RULES["prediction"].value("ltv_over_global") for v in views)
    if k:
        causes.append(f"at the lowest level the LTV model predicts worse than the best global one on {of(k)}")
    k = sum(not v["accurate"] for v in views)
    if k and scale is not None:
        pct = 100 * RULES["prediction"].value("ltv_state_fraction")
        causes.append(f"the lowest level's LTV error is {pct:g} % of the RMS state or more on {of(k)}")
    if not all(v["local"] for v in views):
        worst = max((v["spread"] for v in views if v["spread"] is not None), default=None)
        causes.append(
            f"the data did not stay local even at the lowest level (spread {_f(worst)} >= "
            f"{LOCAL_SPREAD:g}): the perturbed trajectories move about as far from the optimum "
            "as the manoeuvre itself, where no model is local"
        )
    return (" Cause: " + "; ".join(causes) + ".") if causes else ""


def _mlp_epochs_text(res: dict, levels: list) -> str:
    """How long each MLP of a prediction run trained, per level (where the run kept it)."""
    names = [n for n in res[levels[0]] if n.startswith("MLP") and "epochs" in res[levels[0]][n]]
    parts = []
    for n in names:
        runs = [res[lv][n] for lv in levels]
        if all(r.get("best_epoch") not in (None, r["epochs"]) for r in runs):
            what = "stopped at its validation minimum, best epoch " + ", ".join(
                f"{r['best_epoch']} of {r['epochs']}" for r in runs
            )
        else:
            what = "trained " + ", ".join(str(r["epochs"]) for r in runs) + " epochs"
        parts.append(f"{n} {what}")
    return (" " + "; ".join(parts) + " (by level).") if parts else ""


def _devices_text() -> str:
    """The machine the experiments ran on: cores and the JAX devices they were split into."""
    import jax

    d = jax.devices()
    return (
        f"Machine: {os.cpu_count()} CPU cores; {len(d)} JAX {d[0].platform} device(s) "
        "(`--cpu-devices`, docs/scaling.md)."
    )


PRESET_MLPS = (
    "The prediction and control presets train theirs to the minimum of a validation set of "
    "whole training trajectories (`surrogate.mlp.patience`), the prediction presets with the "
    "paper's fixed-epoch network beside it (`surrogate.mlp.fixed_epochs_beside`)."
)


def _mlp_training_text(a: dict) -> str:
    """How long the analysis' MLPs trained (the convergence and variance figures)."""
    runs = {k: v for k, v in (a.get("convergence") or {}).items() if k.startswith("MLP") and "epochs" in v}
    d = (a.get("variance") or {}).get("_mlp_training")
    if d:
        runs["MLP descent directions"] = d
    if not runs:
        return PRESET_MLPS
    return (
        "The convergence and variance MLPs train up to the paper's 5000 epochs with the "
        "convergence test of `configs/cartpole_analysis.py` (`surrogate.mlp.stop_window`, "
        "`stop_rel_tol`): "
        + "; ".join(
            f"{k}: {min(v['epochs'])}-{max(v['epochs'])} epochs, {_f(v['train_s'])} s for "
            f"{len(v['epochs'])} networks together"
            for k, v in runs.items()
        )
        + ". "
        + PRESET_MLPS
    )


def _section(lines, title, caption, figures, measured, verdict, note=""):
    quote = f"> {caption[1:-1]}" if caption.startswith("(") else f'> Paper: "{caption}"'
    lines += [f"### {title}", "", quote, ""]
    lines += [f"![{os.path.basename(f)}]({f})" for f in figures if f]
    lines += ["", f"**Measured.** {measured}", "", f"**Claim:** {verdict}. {note}".rstrip(), ""]


def render(folders: dict, times: dict, fig_dir: str, base: str, quick: bool, wall: float) -> str:
    """The report's Markdown, its figures copied into ``fig_dir`` (links relative to
    ``base``), from the run folders of each experiment (None: missing)."""
    os.makedirs(fig_dir, exist_ok=True)

    def fig(name: str, file: str) -> str | None:
        src = os.path.join(folders.get(name) or "", file)
        if not folders.get(name) or not os.path.exists(src):
            return None
        dst = os.path.join(fig_dir, f"{name}__{file}")
        shutil.copyfile(src, dst)
        return os.path.relpath(dst, base)

    L = _header(folders, times, quick, wall)
    _prediction_sections(L, folders, fig)
    a = _load(folders.get("cartpole_analysis"))
    _analysis_sections(L, a, fig)
    report_control.control_sections(L, folders, fig, _section, _verdict, _f, _read)
    report_control.swimmer15_section(L, folders, fig, _section, _verdict, _f)
    _theory_section(L, folders, fig)
    report_control.horizon_sections(L, folders, fig, _section, _verdict, _f)
    report_pde.pde_sections(L, folders, fig, _section, _verdict, _f, _read)
    report_mpc.closed_loop_sections(L, folders, fig, _section, _read)
    _reading(L, folders, a)
    L += rules_table()
    return "\n".join(L) + "\n"


def _run_commit(folder: str | None) -> str:
    """The commit a run folder's code came from (its ``versions.json``)."""
    path = os.path.join(folder or "", "versions.json")
    if not folder or not os.path.exists(path):
        return "-"
    return read_json(path).get("mjx_surrogate_commit", "not recorded")


# What a run does not execute: a commit that changed only these ran the same code.
NOT_RUN = (":!docs", ":!*.md", ":!tests", ":!benchmarks", ":!experiments/report*.py")


def code_differs(run_commit: str, commit: str, root: str | None = None) -> bool:
    """Whether a run made at ``run_commit`` executed other code than ``commit`` holds: a
    tracked file differs between the two outside ``NOT_RUN`` (the docs, the tests, the
    benchmarks, the report's own modules). A commit git cannot read (``+dirty``, ``unknown``)
    differs."""
    import subprocess

    if run_commit == commit:
        return False
    root = root or os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    try:
        done = subprocess.run(
            ["git", "-C", root, "diff", "--quiet", run_commit, commit, "--", ".", *NOT_RUN],
            capture_output=True,
            timeout=30,
        )
    except (OSError, subprocess.SubprocessError):
        return True
    return done.returncode != 0


def _provenance(commits: dict, commit: str) -> str:
    """The header's sentence on where the runs' code came from."""
    other = [n for n, c in commits.items() if c not in ("-", commit)]
    if not other:
        return "Every run below comes from this commit."
    differs = [n for n in other if code_differs(commits[n], commit)]
    return f"{len(other)} of the runs below come from an earlier commit" + (
        f"; of them {', '.join(differs)} ran code that differs from this commit's: their "
        "numbers describe that code, not this one."
        if differs
        else ", whose code is this commit's: only the docs, tests, benchmarks or the "
        "report's own modules changed since."
    )


def _header(folders: dict, times: dict, quick: bool, wall: float) -> list[str]:
    v = versions()
    commit = v.pop("mjx_surrogate_commit")
    now = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    commits = {n: _run_commit(folders.get(n)) for n in folders}
    L = [
        "# Reproduction report" + (" (--quick: pipeline check, not evidence)" if quick else ""),
        "",
        f"**Code: commit `{commit}`; written {now}.** " + _provenance(commits, commit),
        "",
        "Generated by `python -m experiments.reproduce" + (" --quick" if quick else "") + "`. "
        "Every number below is read from the run folders' `metrics.json`; figures are copied "
        "from them. Versions: " + ", ".join(f"{k} {v}" for k, v in v.items()) + ". " + _devices_text(),
        "",
        "| experiment | run folder | commit | wall time (s) |",
        "|---|---|---|---|",
    ]
    L += [
        f"| {n} | `{folders.get(n) or 'missing'}` | `{commits[n]}` | {_f(times.get(n), 4)} |" for n in folders
    ]
    return L + [
        f"\nTotal wall time of the experiments on this machine: "
        f"{_f(sum(times.values()), 4)} s, each experiment timed by the invocation that ran "
        f"it (this invocation: {wall:.0f} s).",
        "",
    ]


PREDICTIONS = (
    (
        "pendulum_predict",
        "Pendulum swing-up (Fig. LTV)",
        "Comparing the performance of the nonlinear SINDY and MLP models with the LTV model "
        "on swing-up pendulum trajectories.",
        ("predict_10pct.png", "predict_60pct.png"),
    ),
    (
        "cartpole_predict",
        "Cartpole swing-up (Fig. LTV_Cartpole)",
        "Comparing the performance of the SINDY and MLP models with the LTV model on "
        "swing-up Cartpole trajectories.",
        ("predict_10pct.png", "predict_60pct.png"),
    ),
    (
        "fish_predict",
        "Fish (Fig. Fish)",
        "Performance of the surrogate models on Fish trajectories.",
        ("predict_5pct.png", "predict_30pct.png"),
    ),
)


def _prediction_sections(L: list, folders: dict, fig) -> None:
    L += ["## Sampling distributions and predictions", ""]
    for name, title, caption, figs in PREDICTIONS:
        m = _load(folders.get(name))
        held, text = _predict_claim(m, _state_scale(folders.get(name)))
        figs = [fig(name, f) for f in figs] + [
            fig(name, n) for n in ("multi_step_median_vs_level.png", "locality.png")
        ]
        table = _read(folders.get(name), "rmse_table.md")
        measured = text + ("\n\n" + table if table else "")
        _section(L, title, caption, figs, measured, _verdict(held), RULES["prediction"].note())


CONVERGENCE = (
    (
        "SINDy",
        ("convergence_sindy_10pct.png", "convergence_sindy_100pct.png"),
        "Convergence of the SINDY model learned on datasets with random initial seeds, with "
        "perturbations of 10% U_max (a)-(b), and 100% U_max (c)-(d) w.r.t. the optimal swingup "
        "trajectory.",
    ),
    (
        "MLP",
        ("convergence_mlp_5pct.png", "convergence_mlp_25pct.png"),
        "Convergence of the MLP model learned on datasets with random initial seeds, with "
        "perturbations of 5% and 25% U_max w.r.t. the optimal swingup trajectory.",
    ),
)


def _analysis_sections(L: list, a: dict, fig) -> None:
    """Convergence across seeds, Gram conditioning and variance (cartpole_analysis)."""
    L += ["## Model convergence, ill-conditioning and variance (cartpole)", ""]
    conv = a.get("convergence", {})
    for kind, files, caption in CONVERGENCE:
        rows = {k: v for k, v in conv.items() if k.startswith(kind)}
        held = convergence_claim(rows)
        text = (
            "Spread of the predicted trajectories across data sets (mean std; relative to the RMS "
            "state along the optimum, with its 90 % bootstrap interval over the data sets): "
            + ", ".join(
                f"{k}: {_f(v['prediction_spread'])} ({_f(v.get('relative_spread'))}, "
                f"[{', '.join(_f(b) for b in v.get('relative_spread_interval') or [None, None])}])"
                for k, v in rows.items()
            )
            + "."
        )
        figs = [fig("cartpole_analysis", f) for f in files]
        _section(
            L,
            f"{kind} convergence across seeds",
            caption,
            figs,
            text,
            _verdict(held),
            RULES["convergence"].note(),
        )
    _conditioning_sections(L, a.get("ill_conditioning", {}), fig)
    _variance_sections(L, a.get("variance", {}), fig)
    report_ltv.ltv_sections(L, a, _section, _verdict, _f)


def _ill_conditioned(rows: dict, key: str = "condition") -> bool | None:
    """Every model's condition number (``key``) above the rule's floor; None where a row
    lacks it (a run from before it was kept) or there are none."""
    floor = RULES["ill_conditioning"].value("min_condition")
    if not rows or any(key not in v for v in rows.values()):
        return None
    return all(v[key] is None or v[key] > floor for v in rows.values())


def _conditioning_sections(L: list, ill: dict, fig) -> None:
    sindy_c = {k: v for k, v in ill.items() if k.startswith("SINDy")}
    mlp_c = {k: v for k, v in ill.items() if k.startswith("MLP")}
    _section(
        L,
        "SINDy Gram conditioning (Fig. IllCond_SINDY)",
        "Conditioning of the SINDY model learned on perturbations of 5% U_max w.r.t. the "
        "optimal Cartpole swingup trajectory. We assume two sets of basis functions.",
        [fig("cartpole_analysis", "gram_spectra.png")],
        "; ".join(f"{k}: cond {_f(v['condition'])} ({v['precision']})" for k, v in sindy_c.items()),
        _verdict(_ill_conditioned(sindy_c)),
        RULES["ill_conditioning"].note(),
    )
    _section(
        L,
        "MLP Gram conditioning (Fig. IllCond MLP)",
        "Observing the conditioning of the MLP model learned on perturbations of (a) 5% and "
        "(b) 15% of U_max w.r.t. the optimal Cartpole swingup trajectory.",
        [],
        "; ".join(
            f"{k}: a null space of {v.get('null_space', v['eigenvalues_below_1e-12_of_max'])} of "
            f"{v['n_params']} eigenvalues (at least {v.get('hidden_unit_symmetries', '?')}: one scaling "
            f"symmetry per ReLU unit, so the whole Gram is singular by construction, cond "
            f"{_f(v['condition'])}), cond of the rest {_f(v.get('condition_of_the_rest'))}"
            for k, v in mlp_c.items()
        ),
        _verdict(_ill_conditioned(mlp_c, "condition_of_the_rest")),
        RULES["ill_conditioning"].note()
        + " For the MLP, judged on the spectrum apart from its null space."
        + " (Spectra in the SINDy figure above.)",
    )


def _variance_sections(L: list, var: dict, fig) -> None:
    sv = {k: v for k, v in var.items() if k.startswith("SINDy")}
    vals = [v["projection_std_mean"] for v in sv.values()]
    _section(
        L,
        "SINDy variance (Fig. Variance_SINDY)",
        "Variance in the SINDY model, learned on perturbations of 5% and 15% of U_max w.r.t. "
        "the optimal Cartpole swingup trajectory.",
        [fig("cartpole_analysis", "variance_projections.png")],
        "Std across data sets of the error projections (1/R) Theta'(y - Theta C_pooled), mean "
        "over basis functions: " + ", ".join(f"{k}: {_f(v['projection_std_mean'])}" for k, v in sv.items()),
        _verdict(vals[-1] > vals[0] if len(vals) >= 2 else None),
        RULES["sindy_variance"].note(),
    )
    mv = {k: v for k, v in var.items() if k.startswith("MLP")}
    _section(
        L,
        "MLP variance (Fig. Variance MLP)",
        "Variance in the MLP model training, learned on perturbations of 5% of U_max w.r.t. "
        "the optimal Cartpole swingup trajectory.",
        [fig("cartpole_analysis", "mlp_descent_directions.png")],
        "Mean pairwise cosine between the descent directions (1/R) H' Delta of networks with "
        "the same training seed on different data sets, beside the same-data control (one data "
        "set, different seeds), with 90 % bootstrap intervals over the networks: "
        + ", ".join(f"{k}: {_mlp_cosines(v)}" for k, v in mv.items()),
        _verdict(mlp_variance_claim(mv)),
        RULES["mlp_variance"].note(),
    )


def _mlp_cosines(v: dict) -> str:
    text = _f(v["mean_pairwise_cosine"])
    if "same_data_cosine_interval" not in v:
        return text + " (no same-data control in this run)"
    ci, cc = v["mean_pairwise_cosine_interval"], v["same_data_cosine_interval"]
    return (
        f"{text} [{_f(ci[0])}, {_f(ci[1])}] across data sets against {_f(v['same_data_cosine'])} "
        f"[{_f(cc[0])}, {_f(cc[1])}] across seeds"
    )


THEORY_TITLES = {
    "theory_monomial": "The monomial basis's variance formula",
    "theory_hermite": "The Hermite basis's variance formula",
    "theory_legendre": "The Legendre basis's variance formula",
    "theory_condition": "The conditioning estimate",
}
THEORY_CAUSES = {
    "theory_hermite": "The printed formula keeps only the leading monomial and carries a sigma^(2N) "
    "factor, while the normalised basis He_N(x/sigma)/sqrt(N!) is scale-free: its exact variance "
    "(2, 14, 92, 638, ...) is the same for every sigma.",
    "theory_legendre": "The printed formula grows combinatorially while the exact variance of the "
    "normalised Legendre basis grows slowly (about 2.5x from N = 1 to 10): the claimed "
    "combinatorial-exponential sample complexity is not that of this basis.",
    "theory_condition": "G_NN / G_00 is the ratio of two diagonal entries, a lower bound on the "
    "condition number that ignores how nearly collinear the monomials are; the exact condition "
    "number grows faster (see the table).",
}


def _theory_section(L: list, folders: dict, fig) -> None:
    """One verdict per printed formula, each judged by the range of paper / exact over every
    order and scale (``report_rules.theory_claim``)."""
    t = _load(folders.get("theory"))
    L += ['## The theory, numerically (Section "Data Driven Solutions")', ""]
    figs = (
        [fig("theory", f) for f in sorted(os.listdir(folders["theory"])) if f.endswith(".png")]
        if folders.get("theory")
        else []
    )
    fnd = t.get("findings", {})
    table = _read(folders.get("theory"), "theory_table.md")
    for i, (name, title) in enumerate(THEORY_TITLES.items()):
        held, lo, hi = theory_claim(fnd, name)
        if held is None:
            measured = "not run" if not fnd else "this run predates the finding (rerun the theory experiment)"
        else:
            measured = (
                f"paper / exact from {_f(lo)} to {_f(hi)} over orders 1 to {len(t.get('orders', []))} "
                f"and scales {', '.join(fnd)}."
            )
            if not held and name in THEORY_CAUSES:
                measured += " Cause: " + THEORY_CAUSES[name]
        if i == 0 and table:
            measured += "\n\n" + table
        caption = "(no figure in the paper; its Section 3 formulas)"
        _section(L, title, caption, figs if i == 0 else [], measured, _verdict(held), RULES[name].note())


def _reading(L: list, folders: dict, a: dict) -> None:
    L += ["## Reading these results", ""]
    for name in ("pendulum_predict", "cartpole_predict", "fish_predict"):
        loc = _load(folders.get(name)).get("locality") or {}
        spread = loc.get("relative_spread") or {}
        if not spread:
            continue
        local = [float(lv) for lv, v in spread.items() if v is not None and v < LOCAL_SPREAD]
        upto = f"up to {100 * max(local):g} % U_max" if local else "at no level"
        L += [
            f"- {name}: the optimum's open-loop gain is {_f(loc.get('open_loop_gain'))}; its "
            f"data sets stay local (median relative spread below {LOCAL_SPREAD:g}) {upto}."
        ]
    L += [
        "- " + _mlp_training_text(a),
        "- The run folders named above are local (`runs/` is not versioned); rerun "
        "`python -m experiments.reproduce` to regenerate them and this report.",
        "",
    ]
