"""`python -m experiments.reproduce --quick`: every experiment, every figure, the report;
and resuming skips finished experiments."""

import os
import re

from experiments import reproduce

FIGURES = {
    "pendulum_predict": ["predict_10pct.png", "predict_60pct.png"],
    "cartpole_predict": ["predict_10pct.png", "predict_60pct.png"],
    "fish_predict": ["predict_5pct.png", "predict_30pct.png"],
    "cartpole_analysis": ["convergence_sindy_10pct.png", "convergence_sindy_100pct.png",
                          "convergence_mlp_5pct.png", "convergence_mlp_25pct.png",
                          "gram_spectra.png", "variance_projections.png",
                          "mlp_descent_directions.png"],
    "theory": ["theory_variance_sigma1.png", "theory_condition_sigma1.png"],
    "cartpole_control": ["ltv_trajectory_evolution.png", "surrogate_controls.png"],
}


def test_quick_reproduction_produces_every_figure_and_resumes(tmp_path, capsys):
    out, report = tmp_path / "runs", tmp_path / "report.md"
    assert reproduce.main(["--quick", "--out", str(out), "--report", str(report)]) == 0
    for name, files in FIGURES.items():
        folder = reproduce.finished(str(out), name)
        assert folder, name
        missing = [f for f in files if not os.path.exists(os.path.join(folder, f))]
        assert not missing, (name, missing)
    text = report.read_text()
    for section in ("Fig. LTV", "Fig. LTV_Cartpole", "Fig. Fish", "SINDy convergence",
                    "MLP convergence", "Fig. IllCond_SINDY", "Fig. IllCond MLP",
                    "Fig. Variance_SINDY", "Fig. Variance MLP", "Fig. control", "order N"):
        assert section in text, section
    for link in re.findall(r"\]\(([^)]+\.png)\)", text):
        assert os.path.exists(tmp_path / link), link
    capsys.readouterr()
    assert reproduce.main(["--quick", "--out", str(out), "--report", str(report)]) == 0
    assert capsys.readouterr().out.count("done already") == len(FIGURES)
