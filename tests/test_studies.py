"""The "theory" experiment end to end on its smoke preset. The other kinds' outputs are
checked on the quick reproduction's run folders (tests/test_reproduce.py)."""

import json
import os

from experiments import run as cli


def _run(preset, tmp_path):
    assert cli.main([preset, "--out", str(tmp_path)]) == 0
    (folder,) = os.listdir(tmp_path)
    return tmp_path / folder


def test_smoke_theory_reports_exact_monte_carlo_and_paper(tmp_path):
    path = _run("smoke_theory", tmp_path)
    m = json.loads((path / "metrics.json").read_text())
    d = m["by_sigma"]["1"]
    assert d["monomial"]["var_exact"] == d["monomial"]["var_paper"]
    assert m["findings"]["1"]["monomial_variance_formula_exact"]
    assert {"theory_variance_sigma1.png", "theory_condition_sigma1.png", "theory_table.md"} <= set(
        os.listdir(path)
    )
