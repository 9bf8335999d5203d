"""The reproduction report's claims and the rules that judge them, as data.

Each :class:`Rule` names whose claim it is, the claim, the rule that decides it on the
measured numbers (in words, with its thresholds filled in) and the thresholds themselves;
the report's sections read their thresholds here, state each rule under its verdict
(:meth:`Rule.note`) and end with the table of all of them (:func:`rules_table`).
"""

from __future__ import annotations

from typing import NamedTuple

from mjx_surrogate.analysis.closed_loop import MATCH_TOL, WORKS_FACTOR


class Rule(NamedTuple):
    """``rule`` may name a threshold as ``{name}`` (printed with ``:g``) or ``{name_pct}``
    (100 x the threshold, a percentage)."""

    source: str
    claim: str
    rule: str
    thresholds: tuple[tuple[str, float], ...] = ()

    def value(self, name: str) -> float:
        """A threshold by name."""
        return dict(self.thresholds)[name]

    def rule_text(self) -> str:
        values = {k: f"{v:g}" for k, v in self.thresholds}
        values |= {f"{k}_pct": f"{100 * v:g}" for k, v in self.thresholds}
        return self.rule.format(**values)

    def note(self) -> str:
        """The line under a section's verdict."""
        return f"Claim ({self.source}): {self.claim} (rule: {self.rule_text()})."


RULES: dict[str, Rule] = {
    "prediction": Rule(
        "the paper's",
        "the global models' error grows with the perturbation level while the local LTV model "
        "stays accurate near its trajectory",
        "every global model's error grows from the lowest to the highest level; at the lowest "
        "level the LTV error is below {ltv_state_fraction_pct} % of the RMS state along the "
        "optimum and at most {ltv_over_global}x the best global model's (the local model "
        "predicts at least as well as every global one); the lowest level's data stayed local, "
        "median relative spread below {local_spread}",
        (("ltv_state_fraction", 0.1), ("ltv_over_global", 1.0), ("local_spread", 0.5)),
    ),
    "convergence": Rule(
        "the paper's",
        "the spread across seeds grows with the perturbation level",
        "the spread of the predicted trajectories across data sets (relative to the RMS state "
        "along the optimum) at the highest level exceeds the lowest level's by at least "
        "{min_effect_pct} % of the state, and their 90 % bootstrap intervals over the data sets "
        "do not overlap",
        (("min_effect", 0.01),),
    ),
    "ill_conditioning": Rule(
        "the paper's",
        "the Gram matrix is severely ill-conditioned",
        "every model's condition number is above {min_condition}, or infinite",
        (("min_condition", 1e6),),
    ),
    "sindy_variance": Rule(
        "the paper's",
        "the spread grows with basis order and perturbation level",
        "the last library's mean spread of the error projections exceeds the first's",
    ),
    "mlp_variance": Rule(
        "the paper's",
        "different data sets give different descent directions",
        "at epoch 0 and once trained, the mean pairwise cosine between the descent directions "
        "of networks with the same training seed on different data sets is below {max_cosine} "
        "and at least {min_effect} below the same-data control's (one data set, the training "
        "seeds differ), with the 90 % bootstrap intervals over the networks apart",
        (("max_cosine", 0.99), ("min_effect", 0.1)),
    ),
    "ltv_gram": Rule(
        "the paper's",
        "the local LTV regression's Gram matrix dX' dX is well conditioned and the variance of "
        "its right-hand side is low",
        "under every sampling distribution the largest over the seeds of the median over t of "
        "the Gram's condition number (scaled to a unit diagonal, as the solver solves it) is "
        "below {max_condition} and below every SINDy library's at the same scaling, and the "
        "spread of its error projections across seeds, relative to the right-hand side, is "
        "below every SINDy variance library's",
        (("max_condition", 100.0),),
    ),
    "ltv_distribution": Rule(
        "the paper's",
        "the sampling distribution is immaterial to the local LTV estimate, which is accurate",
        "under every sampling distribution the largest over the seeds of the [A B] error (median "
        "over t, relative to central finite differences) is below {max_error_pct} %, and the "
        "distributions' median errors are within a factor {factor} of each other",
        (("max_error", 0.01), ("factor", 2.0)),
    ),
    "theory_monomial": Rule(
        "the paper's, Section 3",
        "under N(0, sigma^2) the monomial Gram entry x^(2N) has variance "
        "[(4N-1)!! - ((2N-1)!!)^2] sigma^(4N)",
        "the printed formula over the exact variance (rational moments) is within 1 +- {rtol} at "
        "every order and scale",
        (("rtol", 1e-9),),
    ),
    "theory_hermite": Rule(
        "the paper's, Section 3",
        "the Hermite basis's Gram entry has variance [(4N-1)!! - ((2N-1)!!)^2] / (N!)^2 sigma^(2N)",
        "the printed formula is within a factor {factor} of the exact variance of the normalised "
        "basis He_N(x / sigma) / sqrt(N!) at every order and scale",
        (("factor", 2.0),),
    ),
    "theory_legendre": Rule(
        "the paper's, Section 3",
        "the Legendre basis's Gram entry has variance (2N)!^2 4N^2 / ((N!)^4 (2N+1)^2 (4N+1)) "
        "sigma^(2N) (a combinatorial-exponential sample complexity)",
        "the printed formula is within a factor {factor} of the exact variance of the normalised "
        "basis sqrt(2N+1) P_N(x / sigma) under U(-sigma, sigma) at every order and scale",
        (("factor", 2.0),),
    ),
    "theory_condition": Rule(
        "the paper's, Section 3",
        "the monomial Gram's condition number grows like G_NN / G_00 = (2N-1)!! sigma^(2N)",
        "the estimate is within a factor {factor} (an order of magnitude) of the exact condition "
        "number at every order and scale",
        (("factor", 10.0),),
    ),
    "control": Rule(
        "the paper's",
        "the LTV approach reaches the optimum from a random start; the surrogate-based controllers do not",
        "D2C converged, within {exact_gap_pct} % of the exact oracle where it ran (from the "
        "run's start and from each of `experiment.control.starts` random starts), and every "
        "surrogate-based controller (every model, level and seed) is more than "
        "{surrogate_worse_pct} % worse than D2C on the black box",
        (("exact_gap", 0.01), ("surrogate_worse", 0.01)),
    ),
    "swimmer15": Rule(
        "this project's",
        "D2C converges on the 15-link swimmer",
        "the solve from every one of the run's random starts (`solver.n_starts`; each start's own "
        "end, before any search past a stall) is converged: the relative cost change fell below "
        "`rel_tol` (or another minimum test held), not stalled, not at its iteration budget",
    ),
    "horizon": Rule(
        "Pfrommer et al.",
        "under the gains the rollouts stay close to the nominal and the identified closed-loop "
        "model keeps its accuracy to the end of the horizon",
        "at every level the closed-loop rollouts' spread at T is below the open-loop rollouts', "
        "and the error of A + BK over the last quarter of the horizon is no larger",
    ),
    "ro_d2c": Rule(
        "this project's",
        "RO-D2C converges to the exact oracle's cost",
        "converged, and within {gap_pct} % of the oracle's cost",
        (("gap", 0.01),),
    ),
    "pde_prediction": Rule(
        "the paper's, carried to a PDE",
        "a local LTV model predicts the trajectories near the optimum better than every global surrogate",
        "on every data set of the lowest level the best local model's multi-step error is below "
        "the best global model's",
    ),
    "closed_loop": Rule(
        "the paper's, carried into closed loop",
        "global surrogates fail where local LTV models (D2C-MPC) work",
        "judged where D2C-MPC's median cost is finite and at most {works_factor}x the offline "
        "optimum's; a surrogate's MPC matches it when its median cost is within {match_tol_pct} % "
        "and it reaches the goal as often; held where none matches in any judged condition, did "
        "not hold where one matches in every one, in part otherwise",
        (("works_factor", WORKS_FACTOR), ("match_tol", MATCH_TOL)),
    ),
}


# theory rule -> the finding that judges it (``theory_study._findings``: [min, max] of paper / exact)
THEORY = {
    "theory_monomial": "monomial_variance_paper_over_exact",
    "theory_hermite": "hermite_variance_paper_over_exact",
    "theory_legendre": "legendre_variance_paper_over_exact",
    "theory_condition": "monomial_condition_paper_over_exact",
}


def theory_claim(findings: dict, name: str) -> tuple[bool | None, float | None, float | None]:
    """(held, lowest, highest paper / exact over every scale and order) for the theory rule
    ``name``; held is None where the finding is missing (a run from before it was kept)."""
    ranges = [d[THEORY[name]] for d in findings.values() if THEORY[name] in d]
    if not ranges:
        return None, None, None
    lo, hi = min(r[0] for r in ranges), max(r[1] for r in ranges)
    t = dict(RULES[name].thresholds)
    top = 1 + t["rtol"] if "rtol" in t else t["factor"]
    bottom = 1 - t["rtol"] if "rtol" in t else 1 / t["factor"]
    return bool(bottom <= lo and hi <= top), lo, hi


def convergence_claim(rows: dict) -> bool | None:
    """The convergence rule on one model kind's rows (level order), each with
    ``relative_spread`` and its ``relative_spread_interval``; None with fewer than two
    levels or rows from before those were kept."""
    rows = list(rows.values())
    if len(rows) < 2 or any("relative_spread_interval" not in r for r in rows):
        return None
    lo, hi = rows[0], rows[-1]
    effect = hi["relative_spread"] - lo["relative_spread"]
    apart = hi["relative_spread_interval"][0] > lo["relative_spread_interval"][1]
    return bool(effect >= RULES["convergence"].value("min_effect") and apart)


def mlp_variance_claim(rows: dict) -> bool | None:
    """The ``mlp_variance`` rule on the variance stage's MLP rows (epoch 0, trained); None
    where there are none or they come from before the same-data control was kept."""
    rows = list(rows.values())
    if not rows or any("same_data_cosine_interval" not in r for r in rows):
        return None
    t = dict(RULES["mlp_variance"].thresholds)
    return all(
        r["mean_pairwise_cosine"] < t["max_cosine"]
        and r["same_data_cosine"] - r["mean_pairwise_cosine"] >= t["min_effect"]
        and r["mean_pairwise_cosine_interval"][1] < r["same_data_cosine_interval"][0]
        for r in rows
    )


def _rows(ltv: dict) -> dict:
    return {k: v for k, v in (ltv or {}).items() if not k.startswith("_")}


def ltv_gram_claim(ltv: dict, ill: dict, var: dict) -> bool | None:
    """The ``ltv_gram`` rule on the analysis stages ``ltv``, ``ill_conditioning`` and
    ``variance``; None where a stage (or its unit-diagonal condition) is missing."""
    rows = _rows(ltv)
    sindy_c = [v.get("condition_unit_diagonal") for k, v in ill.items() if k.startswith("SINDy")]
    sindy_v = [v["relative_to_rhs"] for k, v in var.items() if k.startswith("SINDy")]
    if not rows or not sindy_c or None in sindy_c or not sindy_v:
        return None
    cap = min([RULES["ltv_gram"].value("max_condition"), *sindy_c])
    return all(
        v["condition_unit_diagonal_interval"][1] < cap and v["projection_spread"] < min(sindy_v)
        for v in rows.values()
    )


def ltv_distribution_claim(ltv: dict) -> bool | None:
    """The ``ltv_distribution`` rule on the analysis stage ``ltv``; None where it is missing."""
    rows = _rows(ltv)
    if len(rows) < 2:
        return None
    t = dict(RULES["ltv_distribution"].thresholds)
    medians = [v["model_error"] for v in rows.values()]
    accurate = all(v["model_error_interval"][1] < t["max_error"] for v in rows.values())
    return bool(accurate and max(medians) <= t["factor"] * min(medians))


def rules_table() -> list[str]:
    """The report's last part: every rule, its claim and thresholds."""
    lines = [
        "## The rules behind the verdicts",
        "",
        "Defined in `experiments/report_rules.py`; each section above states its own.",
        "",
        "| rule | whose claim | claim | decided by | thresholds |",
        "|---|---|---|---|---|",
    ]
    for name, r in RULES.items():
        t = ", ".join(f"{k} = {v:g}" for k, v in r.thresholds) or "-"
        lines.append(f"| `{name}` | {r.source} | {r.claim} | {r.rule_text()} | {t} |")
    return lines + [""]
