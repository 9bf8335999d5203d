"""The "predict" experiment end to end on the smoke preset."""

import json
import os

import pytest
from helpers import assert_png

from experiments import run as cli


@pytest.mark.slow
def test_smoke_predict_writes_figures_table_and_metrics(tmp_path):
    assert cli.main(["smoke_predict", "--out", str(tmp_path)]) == 0
    (folder,) = os.listdir(tmp_path)
    path = tmp_path / folder
    files = set(os.listdir(path))
    assert {
        "predict_10pct.png",
        "predict_60pct.png",
        "one_step_rmse_vs_level.png",
        "multi_step_median_vs_level.png",
        "rmse_table.md",
        "arrays.npz",
    } <= files
    for f in files:
        if f.endswith(".png"):
            assert_png(str(path / f))
    m = json.loads((path / "metrics.json").read_text())
    assert m["status"] == "converged" and m["optimum"]["converged"]
    names = {"SINDy cubic_trig", "SINDy quartic", "MLP", "LTV"}
    for level in ("0.1", "0.6"):
        assert names <= set(m["results"][level])
        for name in names:
            assert m["results"][level][name]["one_step_rmse"] is not None
    # near its own trajectory, at the smaller level, the LTV model predicts well
    assert m["results"]["0.1"]["LTV"]["multi_step_median"] < 0.1
    assert "| 10 |" in (path / "rmse_table.md").read_text()


def _run(preset, tmp_path):
    assert cli.main([preset, "--out", str(tmp_path)]) == 0
    (folder,) = os.listdir(tmp_path)
    return tmp_path / folder


@pytest.mark.slow
def test_smoke_analysis_writes_every_figure_and_table(tmp_path, monkeypatch):
    import contextlib

    from mjx_surrogate import progress

    meters, original = {}, progress.steps

    @contextlib.contextmanager
    def recording(desc, total, display=True, **kw):
        with original(desc, total, display, **kw) as meter:
            yield meter
        meters[desc] = (meter.done + 1, meter.total)

    monkeypatch.setattr(progress, "steps", recording)
    path = _run("smoke_analysis", tmp_path)
    # every analysis stage drives a step meter through all of its steps
    for desc in ("analysis: model convergence", "analysis: Gram spectra", "analysis: variance"):
        done, total = meters[desc]
        assert done == total > 0, (desc, meters[desc])
    files = set(os.listdir(path))
    assert {
        "convergence_sindy_10pct.png",
        "convergence_mlp_5pct.png",
        "gram_spectra.png",
        "variance_projections.png",
        "analysis_table.md",
    } <= files
    m = json.loads((path / "metrics.json").read_text())
    assert m["status"] == "converged"
    quartic = m["ill_conditioning"]["SINDy quartic 5%"]
    cubic = m["ill_conditioning"]["SINDy cubic_trig 5%"]
    assert quartic["precision"] == "float64" and quartic["condition"] > cubic["condition"] > 1e3
    assert set(m["variance"]) >= {"SINDy cubic 5%", "SINDy quartic_trig 15%", "MLP 5% epoch 0"}


def test_smoke_theory_reports_exact_monte_carlo_and_paper(tmp_path):
    path = _run("smoke_theory", tmp_path)
    m = json.loads((path / "metrics.json").read_text())
    d = m["by_sigma"]["1"]
    assert d["monomial"]["var_exact"] == d["monomial"]["var_paper"]
    assert m["findings"]["1"]["monomial_variance_formula_exact"]
    assert {"theory_variance_sigma1.png", "theory_condition_sigma1.png", "theory_table.md"} <= set(
        os.listdir(path)
    )


@pytest.mark.slow
def test_smoke_control_judges_surrogate_controllers_on_the_black_box(tmp_path):
    path = _run("smoke_control", tmp_path)
    m = json.loads((path / "metrics.json").read_text())
    assert m["status"] == "converged" and m["d2c"]["cost"] is not None
    assert abs(m["d2c_vs_exact_relative_gap"]) < 0.01
    rows = m["surrogate_rows"]
    assert {r["model"] for r in rows} == {"SINDy cubic_trig", "MLP"}
    # every controller was executed on the black box and its true cost measured (a
    # diverged replay is reported as None and counted here as a measurement too)
    assert all("true_cost_open" in r and "true_cost_closed" in r for r in rows)
    finite = [r["true_cost_over_d2c"] for r in rows if r["true_cost_over_d2c"] is not None]
    assert finite, "no surrogate controller produced a finite true cost"
    # the true cost of any controller is at best the optimum's (D2C within 1 %)
    assert min(finite) > 0.99
    assert "control_table.md" in os.listdir(path)
    for f in ("ltv_trajectory_evolution.png", "surrogate_controls.png"):
        assert_png(str(path / f))
