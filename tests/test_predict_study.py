"""The "predict" experiment end to end on the smoke preset."""

import json
import os

from experiments import run as cli


def test_smoke_predict_writes_figures_table_and_metrics(tmp_path):
    assert cli.main(["smoke_predict", "--out", str(tmp_path)]) == 0
    (folder,) = os.listdir(tmp_path)
    path = tmp_path / folder
    files = set(os.listdir(path))
    assert {"predict_10pct.png", "predict_60pct.png", "one_step_rmse_vs_level.png",
            "multi_step_median_vs_level.png", "rmse_table.md", "arrays.npz"} <= files
    m = json.loads((path / "metrics.json").read_text())
    assert m["status"] == "ok" and m["optimum"]["converged"]
    names = {"SINDy cubic_trig", "SINDy quartic", "MLP", "LTV"}
    for level in ("0.1", "0.6"):
        assert names <= set(m["results"][level])
        for name in names:
            assert m["results"][level][name]["one_step_rmse"] is not None
    # near its own trajectory, at the smaller level, the LTV model predicts well
    assert m["results"]["0.1"]["LTV"]["multi_step_median"] < 0.1
    assert "| 10 |" in (path / "rmse_table.md").read_text()
