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
