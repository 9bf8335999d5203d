"""Report sections for the paper's claims about the local LTV regression itself: its Gram
matrix and variance, and its indifference to the sampling distribution (analysis stage
``ltv``, :mod:`mjx_surrogate.analysis.ltv_sampling`)."""

from __future__ import annotations

from typing import Callable

from experiments.report_rules import RULES, ltv_distribution_claim, ltv_gram_claim

CAPTION = (
    '(no figure in the paper; Section "Sampling Distributions and the Case for Linear '
    'Time-Varying Models": the Gram matrix is well-conditioned and the variance low, the '
    "sampling distribution immaterial)"
)


def ltv_sections(L: list, a: dict, section: Callable, verdict: Callable, f: Callable) -> None:
    """Two sections from the analysis run's metrics ``a`` ({} where it did not run)."""
    ltv = a.get("ltv") or {}
    rows = {k: v for k, v in ltv.items() if not k.startswith("_")}
    setup = ltv.get("_setup", {})
    ill, var = a.get("ill_conditioning", {}), a.get("variance", {})
    if rows:
        head = (
            f"At the optimum, {setup.get('n_samples')} rollouts per data set "
            f"(sigma_x {f(setup.get('sigma_x'))}, sigma_u {f(setup.get('sigma_u'))}), "
            f"{setup.get('n_seeds')} seeds per distribution; intervals are {setup.get('interval')}. "
            + "".join(f"Left out: {why}. " for why in setup.get("left_out", []))
        )
        gram = head + "; ".join(
            f"{k}: cond {f(v['condition_unit_diagonal'])} "
            f"[{', '.join(f(c) for c in v['condition_unit_diagonal_interval'])}] "
            f"(worst t {f(v['condition_unit_diagonal_worst_t'])}, raw {f(v['condition_raw'])}), "
            f"projection spread {f(v['projection_spread'])}"
            for k, v in rows.items()
        )
        gram += ". SINDy at the same scaling: " + ", ".join(
            f"{k} cond {f(v.get('condition_unit_diagonal'))}" for k, v in ill.items() if k.startswith("SINDy")
        )
        gram += "; SINDy projection spread: " + ", ".join(
            f"{k} {f(v['relative_to_rhs'])}" for k, v in var.items() if k.startswith("SINDy")
        )
        dist = (
            head
            + "; ".join(
                f"{k}: [A B] error {f(v['model_error'])} [{f(v['model_error_interval'][0])}, "
                f"{f(v['model_error_interval'][1])}]"
                for k, v in rows.items()
            )
            + f" (reference: {setup.get('reference')})"
        )
    else:
        gram = dist = "not run (this analysis run predates the stage `ltv`, or it did not run)"
    section(
        L,
        "The LTV Gram matrix and its variance",
        CAPTION,
        [],
        gram + ".",
        verdict(ltv_gram_claim(ltv, ill, var)),
        RULES["ltv_gram"].note(),
    )
    section(
        L,
        "The sampling distribution and the LTV estimate",
        CAPTION,
        [],
        dist + ".",
        verdict(ltv_distribution_claim(ltv)),
        RULES["ltv_distribution"].note(),
    )
