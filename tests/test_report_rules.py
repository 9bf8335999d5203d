"""The reproduction report's rules are data (``experiments/report_rules.py``): each states
its thresholds, the verdicts follow them, and the report ends with the table of rules."""

import pytest

from experiments import report, report_rules
from experiments.report_rules import RULES, Rule
from experiments.reproduce import EXPERIMENTS


@pytest.mark.parametrize("name", list(RULES))
def test_every_rule_states_each_of_its_thresholds(name):
    r = RULES[name]
    for key, _ in r.thresholds:
        assert "{" + key + "}" in r.rule or "{" + key + "_pct}" in r.rule, (name, key)
    assert "{" not in r.rule_text(), r.rule_text()
    assert r.note().startswith(f"Claim ({r.source}): {r.claim} (rule: ")


def metrics(ltv_error: float) -> dict:
    """A prediction study's metrics: one global model whose error grows, the LTV model's."""
    return {
        "levels": [0.1, 0.6],
        "results": {
            "0.1": {"SINDy": {"multi_step_median": 1.0}, "LTV": {"multi_step_median": ltv_error}},
            "0.6": {"SINDy": {"multi_step_median": 9.0}, "LTV": {"multi_step_median": 2.0}},
        },
        "finding": {"SINDy": {"grows": True}},
        "locality": {"relative_spread": {"0.1": 0.1, "0.6": 0.9}, "open_loop_gain": 2.0},
    }


def test_the_prediction_verdict_follows_the_rules_thresholds(monkeypatch):
    assert report._predict_claim(metrics(0.05), scale=1.0)[0] is True
    assert report._predict_claim(metrics(0.5), scale=1.0)[0] is False  # above 10 % of the state
    stricter = RULES["prediction"]._replace(
        thresholds=(("ltv_state_fraction", 0.01), ("ltv_over_global", 1.5))
    )
    monkeypatch.setitem(report_rules.RULES, "prediction", stricter)
    assert report._predict_claim(metrics(0.05), scale=1.0)[0] is False


def test_a_local_model_that_predicts_worse_than_the_best_global_one_does_not_hold():
    # accurate against the state (1.2 of a state of 100) but 1.2x the best global model's
    # error: the paper's comparison fails (a 1.5x allowance used to let it hold)
    held, text = report._predict_claim(metrics(1.2), scale=100.0)
    assert held is False and "1.2x the best global model's" in text
    assert "(at each level: 1.2 at 10 %, 0.222 at 60 %)" in text
    assert report._predict_claim(metrics(0.9), scale=100.0)[0] is True


def test_the_report_ends_with_the_table_of_rules(tmp_path):
    text = report.render(
        {n: None for n in EXPERIMENTS}, {}, str(tmp_path / "figures"), str(tmp_path), True, 0.0
    )
    table = text[text.index("## The rules behind the verdicts") :]
    for name, r in RULES.items():
        assert f"| `{name}` | {r.source} | {r.claim} | {r.rule_text()} |" in table
    assert text.count("**Claim:** **not measured**") >= len(EXPERIMENTS) - 2


def test_a_rule_formats_percentages():
    r = Rule("x", "c", "within {tol_pct} % and {tol}", (("tol", 0.05),))
    assert r.rule_text() == "within 5 % and 0.05"


def _theory_findings(sigmas=(0.5, 1.0), max_order=4):
    """The theory experiment's findings, computed as it computes them (exact rational
    moments; a small Monte Carlo that the rules do not read)."""
    from types import SimpleNamespace

    import numpy as np

    from experiments import theory_study

    a = SimpleNamespace(theory_mc_samples=50, theory_mc_trials=4)
    orders = np.arange(1, max_order + 1)
    by = {f"{s:g}": theory_study._one_sigma(a, s, orders, np.random.default_rng(0))[0] for s in sigmas}
    return theory_study._findings({"by_sigma": by})


def test_each_theory_formula_has_its_own_verdict_and_the_numbers_decide_it():
    fnd = _theory_findings()
    held = {name: report_rules.theory_claim(fnd, name)[0] for name in report_rules.THEORY}
    # the monomial formula is exact; the printed Hermite, Legendre and conditioning formulas
    # are off by more than their factors (paper / exact 0.021-5.5, 0.11-150, 0.0086-1)
    assert held == {
        "theory_monomial": True,
        "theory_hermite": False,
        "theory_legendre": False,
        "theory_condition": False,
    }
    _, lo, hi = report_rules.theory_claim(fnd, "theory_hermite")
    assert 0.021 < lo < 0.022 and 5 < hi < 6  # sigma 0.5, N = 4: 13.7 / 638; sigma 1, N = 4: 3500 / 638


@pytest.mark.parametrize(
    "name,contradicting,verdict",
    [
        ("theory_monomial", [1.0, 1.0 + 1e-6], False),  # off by 1e-6: not exact
        ("theory_hermite", [0.9, 1.2], True),  # within a factor 2 everywhere
        ("theory_hermite", [0.6, 2.1], False),
        ("theory_legendre", [0.55, 1.9], True),
        ("theory_condition", [0.2, 3.0], True),  # within an order of magnitude
        ("theory_condition", [0.09, 3.0], False),
    ],
)
def test_a_theory_rule_turns_with_data_that_contradict_it(name, contradicting, verdict):
    fnd = _theory_findings()
    key = report_rules.THEORY[name]
    for d in fnd.values():
        d[key] = list(contradicting)
    assert report_rules.theory_claim(fnd, name)[0] is verdict


def test_the_report_prints_one_theory_verdict_per_formula(tmp_path):
    import json

    folder = tmp_path / "theory"
    folder.mkdir()
    fnd = _theory_findings()
    (folder / "metrics.json").write_text(
        json.dumps({"status": "completed", "findings": fnd, "orders": [1, 2, 3, 4]})
    )
    folders = {n: None for n in EXPERIMENTS} | {"theory": str(folder)}
    text = report.render(folders, {}, str(tmp_path / "figures"), str(tmp_path), True, 0.0)
    part = text[text.index("## The theory, numerically") :]
    part = part[: part.index("\n## ", 1)]
    verdicts = [ln for ln in part.splitlines() if ln.startswith("**Claim:**")]
    assert len(verdicts) == 4 and sum("**held**" in v for v in verdicts) == 1, verdicts
    assert "Cause: The printed formula keeps only the leading monomial" in part


def _conv(lo_spread, lo_interval, hi_spread, hi_interval):
    return {
        "MLP 5%": {"relative_spread": lo_spread, "relative_spread_interval": lo_interval},
        "MLP 25%": {"relative_spread": hi_spread, "relative_spread_interval": hi_interval},
    }


def test_the_convergence_rule_needs_an_effect_the_size_of_the_state_and_apart_intervals():
    from experiments.report_rules import convergence_claim

    assert convergence_claim(_conv(0.01, [0.005, 0.02], 0.2, [0.1, 0.3])) is True
    # growing, with apart intervals, but by 0.4 % of the state: the old order-only rule held
    assert convergence_claim(_conv(0.001, [0.0005, 0.002], 0.005, [0.003, 0.007])) is False
    # a large effect whose intervals overlap: the data sets cannot tell the levels apart
    assert convergence_claim(_conv(0.05, [0.01, 0.2], 0.2, [0.1, 0.3])) is False
    assert convergence_claim(_conv(0.2, [0.1, 0.3], 0.01, [0.005, 0.02])) is False  # shrinking
    assert (
        convergence_claim({"MLP 5%": {"prediction_spread": 0.1}, "MLP 25%": {"prediction_spread": 1.0}})
        is None
    )


def test_the_spread_interval_is_a_bootstrap_over_the_data_sets():
    import jax
    import numpy as np

    from experiments.analysis_study import _spread, spread_interval

    P = np.random.default_rng(0).normal(size=(5, 11, 3))
    lo, hi = spread_interval(P, jax.random.key(0))
    assert lo < _spread(P) < hi and spread_interval(P, jax.random.key(0)) == [lo, hi]
    same = np.broadcast_to(P[:1], P.shape)  # five identical predictions: no spread at all
    assert max(spread_interval(same, jax.random.key(0))) < 1e-12


def test_the_header_names_the_commit_and_the_runs_from_other_commits(tmp_path, monkeypatch):
    import json

    from mjx_surrogate.runs import results

    monkeypatch.setattr(report, "versions", lambda: {"python": "3", "mjx_surrogate_commit": "abc"})
    folders = {n: None for n in EXPERIMENTS}
    for name, commit in (("theory", "abc"), ("pendulum_predict", "old123")):
        (tmp_path / name).mkdir()
        (tmp_path / name / "versions.json").write_text(json.dumps({"mjx_surrogate_commit": commit}))
        (tmp_path / name / "metrics.json").write_text(json.dumps({"status": "failed"}))
        folders[name] = str(tmp_path / name)
    text = report.render(folders, {}, str(tmp_path / "figures"), str(tmp_path), True, 0.0)
    head = text[: text.index("## ")]
    assert "**Code: commit `abc`; written 20" in head
    assert "1 of the runs below come from an earlier commit; of them pendulum_predict ran code that" in head
    assert f"| theory | `{folders['theory']}` | `abc` |" in head
    del folders["pendulum_predict"]
    text = report.render(folders, {}, str(tmp_path / "figures"), str(tmp_path), True, 0.0)
    assert "Every run below comes from this commit." in text
    assert results.code_revision() != "" and "mjx_surrogate_commit" in results.versions()


def test_a_run_from_an_earlier_commit_describes_this_code_only_where_its_code_is_the_same(tmp_path):
    """Only the docs, tests, benchmarks and the report's modules may differ; a change to code
    a run executes, a dirty checkout or an unreadable commit makes the run's code another."""
    import subprocess

    def commit(files: dict[str, str]) -> str:
        for name, text in files.items():
            (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
            (tmp_path / name).write_text(text)
        git = ["git", "-C", str(tmp_path), "-c", "user.name=t", "-c", "user.email=t@t"]
        subprocess.run([*git, "add", "-A"], check=True, capture_output=True)
        subprocess.run([*git, "commit", "-qm", "c"], check=True, capture_output=True)
        head = subprocess.run([*git, "rev-parse", "--short=12", "HEAD"], capture_output=True, text=True)
        return head.stdout.strip()

    subprocess.run(["git", "init", "-q", str(tmp_path)], check=True)
    a = commit({"mjx_surrogate/solver.py": "x = 1\n", "docs/a.md": "a\n", "experiments/report.py": "r\n"})
    b = commit({"docs/a.md": "b\n", "tests/t.py": "t\n", "experiments/report.py": "r2\n", "README.md": "x\n"})
    c = commit({"mjx_surrogate/solver.py": "x = 2\n"})
    d = commit({"experiments/predict_study.py": "p\n"})
    assert not report.code_differs(a, b, str(tmp_path))
    assert report.code_differs(a, c, str(tmp_path)) and report.code_differs(c, d, str(tmp_path))
    root = str(tmp_path)
    assert report.code_differs(a + "+dirty", b, root) and report.code_differs("nothere", b, root)
    assert not report.code_differs(b, b, str(tmp_path))


def test_the_header_says_when_earlier_runs_ran_this_code(monkeypatch):
    monkeypatch.setattr(report, "code_differs", lambda run, head: run == "changed")
    same = report._provenance({"theory": "old", "pendulum_predict": "head", "fish_control": "-"}, "head")
    assert same.startswith("1 of the runs below come from an earlier commit, whose code is this commit's")
    mixed = report._provenance({"theory": "old", "pendulum_predict": "changed"}, "head")
    assert "of them pendulum_predict ran code that differs" in mixed and "theory ran" not in mixed


def _dirs(cos_data, ci_data, cos_seed, ci_seed):
    row = {
        "mean_pairwise_cosine": cos_data,
        "mean_pairwise_cosine_interval": ci_data,
        "same_data_cosine": cos_seed,
        "same_data_cosine_interval": ci_seed,
    }
    return {"MLP 5% epoch 0": row, "MLP 5% trained": row}


def test_the_mlp_variance_rule_needs_the_data_to_move_directions_more_than_the_seed():
    from experiments.report_rules import mlp_variance_claim

    assert mlp_variance_claim(_dirs(0.2, [0.1, 0.3], 0.8, [0.7, 0.9])) is True
    # the measured epoch 0: the data sets' directions agree (0.992); the old rule looked only
    # for some point below 0.99, which the trained point's near-zero gradient always gave
    assert mlp_variance_claim(_dirs(0.992, [0.99, 0.995], 0.3, [0.2, 0.4])) is False
    # directions differ as much when only the seed changes: no sign of the data's variance
    assert mlp_variance_claim(_dirs(0.0, [-0.1, 0.1], 0.05, [-0.05, 0.15])) is False
    # a large effect whose intervals overlap
    assert mlp_variance_claim(_dirs(0.2, [-0.2, 0.6], 0.8, [0.5, 0.95])) is False
    # apart intervals, but the seed-only cosine is higher by 0.05, under the effect asked
    assert mlp_variance_claim(_dirs(0.5, [0.45, 0.52], 0.55, [0.53, 0.6])) is False
    one = _dirs(0.2, [0.1, 0.3], 0.8, [0.7, 0.9])
    one["MLP 5% epoch 0"] = dict(one["MLP 5% epoch 0"], mean_pairwise_cosine=0.995)
    assert mlp_variance_claim(one) is False  # it must hold at both points
    assert mlp_variance_claim({"MLP 5% trained": {"mean_pairwise_cosine": 0.1}}) is None


def test_the_pairwise_cosine_interval_is_a_bootstrap_over_distinct_pairs():
    import numpy as np

    from mjx_surrogate.analysis import spectra

    rng = np.random.default_rng(0)
    V = rng.normal(size=(6, 40)) + 2.0  # a common direction plus noise
    lo, hi = spectra.pairwise_cosine_interval(V, np.random.default_rng(1))
    assert lo < spectra.mean_pairwise_cosine(V) < hi
    # identical rows: every distinct pair has cosine 1 (a row paired with itself is skipped,
    # so a resample cannot pull the mean above or below it)
    same = np.broadcast_to(V[:1], V.shape)
    np.testing.assert_allclose(spectra.pairwise_cosine_interval(same, np.random.default_rng(1)), 1.0)
    orth = np.eye(5)  # orthogonal rows: cosine 0 between every distinct pair, never the diagonal
    np.testing.assert_allclose(spectra.pairwise_cosine_interval(orth, np.random.default_rng(1)), 0.0)


def test_code_revision_is_dirty_for_changed_code_not_for_rewritten_docs(tmp_path):
    """A report rewrites its figures under docs/ before it names the code's commit: those
    (and Markdown) leave the revision clean; a changed tracked code file marks it +dirty;
    outside a checkout it is unknown."""
    import subprocess

    from mjx_surrogate.runs import results

    def git(*args):
        subprocess.run(["git", "-C", str(tmp_path), *args], check=True, capture_output=True)

    (tmp_path / "docs").mkdir()
    (tmp_path / "pkg.py").write_text("x = 1\n")
    (tmp_path / "docs" / "fig.png").write_bytes(b"a")
    (tmp_path / "README.md").write_text("a\n")
    git("init", "-q")
    git("add", ".")
    git("-c", "user.email=t@t", "-c", "user.name=t", "commit", "-q", "-m", "c")
    clean = results.code_revision(str(tmp_path))
    assert len(clean) == 12 and "+" not in clean
    (tmp_path / "docs" / "fig.png").write_bytes(b"b")
    (tmp_path / "README.md").write_text("b\n")
    assert results.code_revision(str(tmp_path)) == clean
    (tmp_path / "pkg.py").write_text("x = 2\n")
    assert results.code_revision(str(tmp_path)) == clean + "+dirty"
    assert results.code_revision(str(tmp_path / "docs")) == "unknown"


def control_metrics(ratios=(3.0, 50.0), gap=1e-6, status="converged", start_gaps=(0.0, 1e-4)) -> dict:
    """A control study's metrics: D2C against the oracle from its start and from random
    starts, and the surrogate rows (true cost over D2C's), one per seed."""
    rows = [{"model": "MLP", "level": 0.05, "seed": s, "true_cost_over_d2c": r} for s, r in enumerate(ratios)]
    starts = [
        {
            "start": i,
            "d2c_cost": 1.0,
            "d2c_status": "converged",
            "relative_gap": g,
            "oracle_status": "converged",
        }
        for i, g in enumerate(start_gaps)
    ]
    return {
        "d2c": {"status": status, "iterations": 40},
        "d2c_vs_exact_relative_gap": gap,
        "surrogate_rows": rows,
        "starts": {"n": len(starts), "rows": starts},
    }


@pytest.mark.parametrize(
    "contradicting, cause",
    [
        ({"ratios": (3.0, 1.005)}, "within 1 % of D2C or better: MLP at 5 % (seed 1)"),  # one seed as good
        ({"ratios": (3.0, 0.9)}, "seed 1"),  # a surrogate beats D2C
        ({"gap": 0.02}, "D2C ended +2 % from the oracle's cost"),
        ({"status": "stalled"}, "did not converge"),
        ({"start_gaps": (0.0, 0.05)}, "from random start 1 D2C ended +5 % from the oracle's cost"),
        ({"start_gaps": (0.0, None)}, "from random start 1 D2C ended without a finite cost"),
        ({"ratios": ()}, "no surrogate-based controller ran"),
    ],
)
def test_the_control_rule_turns_with_data_that_contradict_it(contradicting, cause):
    """Held on metrics that support the paper's claim; not held, with the cause named,
    on each kind of contradicting outcome (a seed's surrogate as good as D2C, D2C off the
    oracle from its own start or from one random start, an unconverged D2C)."""
    from experiments.report_control import control_verdict

    rule = RULES["control"]
    held, worse, causes = control_verdict(control_metrics(), rule)
    assert held is True and len(worse) == 2 and causes == []
    held, _, causes = control_verdict(control_metrics(**contradicting), rule)
    assert held is False and any(cause in c for c in causes), causes
    assert control_verdict({}, rule)[0] is None  # no run: no verdict


def test_rows_whose_ilqr_made_no_step_are_named_as_the_start_replayed():
    from experiments.report_control import _no_step_text

    planned = {"model": "SINDy poly2", "model_cost": 3.0, "iterations": 12}
    stuck = {"model": "MLP", "model_cost": None, "iterations": 0}
    diverged_later = {"model": "SINDy quartic", "model_cost": None, "iterations": 7}
    assert _no_step_text([planned, diverged_later]) == ""
    text = _no_step_text([planned, stuck, stuck, diverged_later])
    assert text.startswith(" In 2 of 4 rows (MLP) iLQR made no step"), text


def test_the_swimmer_rule_needs_every_start_converged():
    """Held only where each start's own solve converged; one stalled start (or a stalled
    single start) turns it, and the text names every start's end."""
    from experiments.report_control import _starts_text, swimmer15_verdict

    def f(v, digits):
        return f"{v:.{digits}g}"

    five = {"status": "converged", "multistart_statuses": ["converged"] * 5, "multistart_costs": [3.0] * 5}
    assert swimmer15_verdict(five) is True
    one_stalled = {**five, "multistart_statuses": ["converged"] * 4 + ["stalled"]}
    assert swimmer15_verdict(one_stalled) is False
    assert swimmer15_verdict({"status": "stalled"}) is False
    assert swimmer15_verdict({"status": "converged"}) is True
    assert swimmer15_verdict({}) is None
    text = _starts_text({**one_stalled, "multistart_costs": [2.0, 3.0, 4.0, 5.0, float("inf")]}, f)
    assert "4 converged, 1 stalled" in text and "costs 2-5" in text, text
