"""`python -m experiments.reproduce --quick`: every experiment, every figure, the report;
and resuming skips finished experiments."""

import json
import os
import re

import pytest
from helpers import assert_png

from experiments import reproduce

FIGURES = {
    "pendulum_predict": ["predict_10pct.png", "predict_60pct.png"],
    "cartpole_predict": ["predict_10pct.png", "predict_60pct.png"],
    "fish_predict": ["predict_5pct.png", "predict_30pct.png"],
    "cartpole_analysis": [
        "convergence_sindy_10pct.png",
        "convergence_sindy_100pct.png",
        "convergence_mlp_5pct.png",
        "convergence_mlp_25pct.png",
        "gram_spectra.png",
        "variance_projections.png",
        "mlp_descent_directions.png",
    ],
    "theory": ["theory_variance_sigma1.png", "theory_condition_sigma1.png"],
    "cartpole_control": ["ltv_trajectory_evolution.png", "surrogate_controls.png"],
}


@pytest.mark.slow
def test_quick_reproduction_produces_every_figure_and_resumes(tmp_path, capsys):
    out, report = tmp_path / "runs", tmp_path / "report.md"
    assert reproduce.main(["--quick", "--out", str(out), "--report", str(report)]) == 0
    for name, files in FIGURES.items():
        folder = reproduce.finished(str(out), name)
        assert folder, name
        for f in files:
            assert_png(os.path.join(folder, f))
    text = report.read_text()
    for section in (
        "Fig. LTV",
        "Fig. LTV_Cartpole",
        "Fig. Fish",
        "SINDy convergence",
        "MLP convergence",
        "Fig. IllCond_SINDY",
        "Fig. IllCond MLP",
        "Fig. Variance_SINDY",
        "Fig. Variance MLP",
        "Fig. control",
        "order N",
    ):
        assert section in text, section
    for link in re.findall(r"\]\(([^)]+\.png)\)", text):
        assert os.path.exists(tmp_path / link), link
    capsys.readouterr()
    assert reproduce.main(["--quick", "--out", str(out), "--report", str(report)]) == 0
    assert capsys.readouterr().out.count("done already") == len(FIGURES)
    # a run that was killed after its first stage resumes from that stage
    theory = reproduce.finished(str(out), "theory")
    mpath = os.path.join(theory, "metrics.json")
    m = json.load(open(mpath))
    original = m["by_sigma"]
    first, second = list(m["stages"])
    del m["stages"][second]
    m["status"] = "killed"
    json.dump(m, open(mpath, "w"))
    assert reproduce.main(["--quick", "--out", str(out), "--report", str(report), "--only", "theory"]) == 0
    assert "resuming the stages" in capsys.readouterr().out
    resumed = json.load(open(os.path.join(reproduce.finished(str(out), "theory"), "metrics.json")))
    assert resumed["status"] == "completed"
    assert resumed["stages"][first].get("resumed") is True
    assert not resumed["stages"][second].get("resumed")
    assert resumed["by_sigma"] == original  # same seed-derived draws: the same numbers
