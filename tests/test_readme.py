"""The README's commands are the ones CI and users run."""

import os
import re

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def test_ci_runs_the_readme_test_command():
    readme = open(os.path.join(ROOT, "README.md")).read()
    blocks = re.findall(r"```bash\n(.*?)\n```", readme, re.S)
    test_cmd = next(b for b in blocks if "pytest" in b)
    assert test_cmd in open(os.path.join(ROOT, ".ci", "run")).read()
    assert any("experiments.run" in b and "pip install" in b for b in blocks)


@pytest.mark.slow
def test_readme_python_example_runs_as_written(capsys):
    readme = open(os.path.join(ROOT, "README.md")).read()
    (block,) = re.findall(r"```python\n(.*?)```", readme, re.S)
    exec(compile(block, "README.md", "exec"), {"__name__": "readme"})
    cost, iterations, verdict = capsys.readouterr().out.split()[-3:]
    assert float(cost) < 1.0 and int(iterations) > 0 and verdict == "converged"
