"""Experiment kind "theory": the paper's variance and conditioning claims for a scalar map,
exact (rational moments) against Monte Carlo and against the paper's printed formulas."""

from __future__ import annotations

from fractions import Fraction

import jax
import numpy as np

from mjx_surrogate.analysis import theory as th
from mjx_surrogate.runs import plots
from mjx_surrogate.runs.resolution import Resolved
from mjx_surrogate.runs.results import Run

BASES = (("monomial", "gauss"), ("hermite", "gauss"), ("legendre", "uniform"))


def _one_sigma(a, sigma: float, orders: np.ndarray, rng) -> tuple[dict, dict, list]:
    s = Fraction(sigma).limit_denominator(10**6)
    out, arrays = {}, {}
    for basis, dist in BASES:
        exact = [float(th.entry_variance(basis, int(n), int(n), dist, s)) for n in orders]
        mean = [float(th.gram_exact(basis, int(n), dist, s)[n][n]) for n in orders]
        cond = [th.condition_number(th.gram_exact(basis, int(n), dist, s)) for n in orders]
        paper = {
            "monomial": th.paper_monomial_variance,
            "hermite": th.paper_hermite_samples,
            "legendre": th.paper_legendre_samples,
        }[basis]
        paper_v = [paper(int(n), sigma) for n in orders]
        needed = [th.samples_needed(v, m) for v, m in zip(exact, mean)]
        # Monte Carlo: variance of G^R_NN across trials, times R, against sigma_NN^2
        mc = []
        for n in orders:
            G = th.monte_carlo_gram(basis, int(n), dist, sigma, a.theory_mc_samples, a.theory_mc_trials, rng)
            mc.append(float(G[:, n, n].var(ddof=1) * a.theory_mc_samples))
        out[basis] = {
            "distribution": dist,
            "var_exact": exact,
            "var_paper": paper_v,
            "var_monte_carlo": mc,
            "gram_NN": mean,
            "condition_exact": cond,
            "samples_for_10pct": needed,
        }
        arrays[f"{basis}_sigma{sigma:g}_var"] = np.array([exact, paper_v, mc])
    out["monomial"]["condition_paper"] = [th.paper_condition(int(n), sigma) for n in orders]
    return out, arrays


def run(res: Resolved, record: Run, key: jax.Array) -> str:
    a = res.config.analysis
    orders = np.arange(1, a.theory_max_order + 1)
    record.set("orders", orders.tolist())
    record.add_arrays({"x0": res.task.x0, "orders": orders})
    rows = []
    for i, sigma in enumerate(a.theory_sigmas):
        # each scale draws from its own stream, so a resumed run gives the same numbers
        seed = int(jax.random.randint(jax.random.fold_in(key, i), (), 0, 2**31 - 1))
        out, _ = record.stage(
            f"by_sigma/{sigma:g}", lambda: _one_sigma(a, sigma, orders, np.random.default_rng(seed))
        )
        for basis, _ in BASES:
            d = out[basis]
            rows += [
                (
                    sigma,
                    basis,
                    int(n),
                    d["var_exact"][i],
                    d["var_paper"][i],
                    d["var_monte_carlo"][i],
                    d["condition_exact"][i],
                    d["samples_for_10pct"][i],
                )
                for i, n in enumerate(orders)
            ]
        record.figure(
            f"theory_variance_sigma{sigma:g}.png",
            lambda: plots.theory_curves(
                orders,
                {f"{b} exact": out[b]["var_exact"] for b, _ in BASES}
                | {f"{b} paper": out[b]["var_paper"] for b, _ in BASES}
                | {f"{b} Monte Carlo": out[b]["var_monte_carlo"] for b, _ in BASES},
                "Var[psi_N^2] (R x variance of G^R_NN)",
                f"variance of the Gram diagonal, scale {sigma:g}",
            ),
        )
        record.figure(
            f"theory_condition_sigma{sigma:g}.png",
            lambda: plots.theory_curves(
                orders,
                {f"{b} exact": out[b]["condition_exact"] for b, _ in BASES}
                | {"monomial, paper G_NN/G_00": out["monomial"]["condition_paper"]},
                "cond(G)",
                f"Gram condition number, scale {sigma:g}",
            ),
        )
    record.set("findings", _findings(record.metrics))
    record.folder.write_text("theory_table.md", _table(rows))
    return "completed"


def _table(rows) -> str:
    head = (
        "| scale | basis | N | Var exact | Var paper | Var Monte Carlo | cond(G) exact "
        "| samples for 10 % |\n|---|---|---|---|---|---|---|---|\n"
    )
    return (
        head
        + "\n".join(
            f"| {s:g} | {b} | {n} | {e:.4g} | {p:.4g} | {m:.4g} | {c:.3g} | {r:.3g} |"
            for s, b, n, e, p, m, c, r in rows
        )
        + "\n"
    )


def _ratio_range(paper: list, exact: list) -> list[float]:
    """[min, max] over the orders of the printed formula over the exact value."""
    r = np.asarray(paper, float) / np.asarray(exact, float)
    return [float(r.min()), float(r.max())]


def _findings(m: dict) -> dict:
    """Per scale, each printed formula against the exact numbers: the range over the orders
    of paper / exact (the report judges each formula by it, ``report_rules.THEORY``)."""
    out = {}
    for sig, d in m["by_sigma"].items():
        leg, her, mono = d["legendre"], d["hermite"], d["monomial"]
        out[sig] = {
            "monomial_variance_formula_exact": bool(
                np.allclose(mono["var_exact"], mono["var_paper"], rtol=1e-9)
            ),
            "monomial_variance_paper_over_exact": _ratio_range(mono["var_paper"], mono["var_exact"]),
            "hermite_variance_paper_over_exact": _ratio_range(her["var_paper"], her["var_exact"]),
            "legendre_variance_paper_over_exact": _ratio_range(leg["var_paper"], leg["var_exact"]),
            "monomial_condition_paper_over_exact": _ratio_range(
                mono["condition_paper"], mono["condition_exact"]
            ),
            "hermite_paper_over_exact_at_max_order": her["var_paper"][-1] / her["var_exact"][-1],
            "legendre_exact_growth_first_to_last": leg["var_exact"][-1] / leg["var_exact"][0],
            "legendre_paper_growth_first_to_last": leg["var_paper"][-1] / leg["var_paper"][0],
            "monomial_condition_growth": mono["condition_exact"][-1] / mono["condition_exact"][0],
        }
    return out
