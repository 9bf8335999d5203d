"""examples/black_box.ipynb runs as written (nbclient, a fresh kernel), and says what it
claims: D2C reaches the oracle's cost on the NumPy black box; a global surrogate whose
library holds the simulator's equations is exact, one whose library does not is beaten by
the local LTV model."""

import os
import re

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.mark.slow
def test_the_black_box_notebook_executes_and_plots_inline(monkeypatch):
    monkeypatch.delenv("MPLBACKEND", raising=False)  # the kernel's own default: inline figures
    import nbformat
    from nbclient import NotebookClient

    nb = nbformat.read(os.path.join(ROOT, "examples", "black_box.ipynb"), as_version=4)
    NotebookClient(nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": ROOT}}).execute()
    text = "\n".join(
        o.get("text", "") for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])
    )
    images = sum("image/png" in o.get("data", {}) for c in nb.cells for o in c.get("outputs", []))
    assert images == 2
    assert "converged goal reached: True" in text, text
    d2c, oracle = map(float, re.search(r"D2C cost ([\d.]+), oracle ([\d.]+)", text).groups())
    assert abs(d2c / oracle - 1) < 1e-3
    rmse = {
        k.strip(): float(v)
        for k, v in re.findall(r"^(.{16}) one-step RMSE \S+\s+open-loop RMSE (\S+)", text, re.M)
    }
    assert rmse["SINDy cubic+trig"] < 1e-9, rmse  # its library holds the simulator's equations
    assert rmse["LTV"] < 0.5 * rmse["SINDy cubic"], rmse  # without them the global fit drifts
