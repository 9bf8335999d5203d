"""The quickstart's code runs as written (docs/quickstart.md)."""

import os
import re

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.mark.slow
def test_quickstart_runs_as_written(capsys):
    text = open(os.path.join(ROOT, "docs", "quickstart.md")).read()
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert len(blocks) >= 5
    namespace: dict = {"__name__": "quickstart"}
    for block in blocks:
        exec(compile(block, "docs/quickstart.md", "exec"), namespace)
    out = capsys.readouterr().out
    assert "D2C cost" in out and "true cost" in out and "multi-step RMSE" in out
