"""The quickstart's code runs as written (docs/quickstart.md)."""

import glob
import json
import os
import re
import shlex

import numpy as np
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


@pytest.mark.slow
def test_your_model_page_runs_as_written(tmp_path, monkeypatch, capsys):
    from thirdparty import model_path

    reacher = model_path("gymnasium", "reacher.xml")
    if reacher is None:
        pytest.skip("gymnasium wheel could not be downloaded")
    monkeypatch.setenv("REACHER_XML", reacher)
    monkeypatch.chdir(tmp_path)
    text = open(os.path.join(ROOT, "docs", "your_model.md")).read()
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert len(blocks) == 4
    namespace: dict = {"__name__": "your_model"}
    for block in blocks:
        exec(compile(block, "docs/your_model.md", "exec"), namespace)
    out = capsys.readouterr().out
    assert "8 2 ['joint0', 'joint1'] [-1.0, 1.0]" in out
    metrics = namespace["metrics"]
    # the first solve stalls; a restart around its start converges far lower (the page's words)
    restart = metrics["d2c"]["restart"]
    assert restart["why"] == "the first solve stalled" and restart["kept"].startswith("restart")
    assert metrics["status"] == "converged" and metrics["d2c"]["goal"]["reached"]
    assert metrics["d2c"]["cost"] < 0.1 * restart["first_cost"]
    assert os.path.isfile(os.path.join(namespace["folder"], "model.mjb"))


@pytest.mark.slow
def test_function_systems_page_runs_as_written(capsys):
    text = open(os.path.join(ROOT, "docs", "function_systems.md")).read()
    block = re.findall(r"```python\n(.*?)```", text, flags=re.S)[0]
    namespace: dict = {"__name__": "function_systems"}
    exec(compile(block, "docs/function_systems.md", "exec"), namespace)
    status, reached, cost, oracle = capsys.readouterr().out.split()
    assert status == "converged" and reached == "True"
    assert abs(float(cost) / float(oracle) - 1) < 1e-3
    U = np.asarray(namespace["d2c"].out.U)
    assert np.all(np.abs(U) <= 5.0) and np.max(np.abs(U)) > 1.0  # the limit shapes the swing-up


@pytest.mark.slow
def test_function_systems_command_line_runs_as_written_and_replays(tmp_path, monkeypatch, capsys):
    """The page's module and command: D2C converges to the central-difference oracle's
    cost, the folder keeps the source, the replay gives the same cost, and once the
    module is edited the replay refuses with one line."""
    from experiments import run as cli

    text = open(os.path.join(ROOT, "docs", "function_systems.md")).read()
    module = next(b for b in re.findall(r"```python\n(.*?)```", text, flags=re.S) if b.startswith("# my_"))
    (command,) = re.findall(r"```bash\n(.*?)```", text, flags=re.S)
    argv = shlex.split(command.replace("\\\n", " "))
    assert argv[:3] == ["python", "-m", "experiments.run"]
    monkeypatch.chdir(tmp_path)
    (tmp_path / "my_pendulum.py").write_text(module)
    assert cli.main(argv[3:] + ["--out", "runs"]) == 0
    (folder,) = glob.glob("runs/*_my_pendulum")
    metrics = json.load(open(os.path.join(folder, "metrics.json")))
    config = json.load(open(os.path.join(folder, "config.json")))
    assert metrics["d2c"]["status"] == "converged" and metrics["d2c"]["goal"]["reached"]
    assert abs(metrics["d2c_vs_exact_relative_gap"]) < 1e-3
    assert config["experiment"]["oracle"] == "finite_difference" and config["experiment"]["x64"]
    assert open(os.path.join(folder, "system_source.py")).read() == module
    replay = os.path.join(folder, "config.json")
    assert cli.main([replay, "--out", "runs"]) == 0
    (again,) = glob.glob("runs/*_my_pendulum_replay")
    assert json.load(open(os.path.join(again, "metrics.json")))["d2c"]["cost"] == metrics["d2c"]["cost"]
    capsys.readouterr()
    (tmp_path / "my_pendulum.py").write_text(module.replace("0.1 * omega", "0.2 * omega"))
    assert cli.main([replay, "--out", "runs"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: system.source_sha256: ")


@pytest.mark.slow
def test_function_systems_module_runs_the_control_study_from_the_command_line(tmp_path, monkeypatch, capsys):
    """The page's NumPy module through the host callback, at tiny sizes: the control
    study (data, surrogate fits, controllers judged on the black box) finishes. The
    prediction study shares its data and fits, and runs on function black boxes in the
    quick reproduction (burgers_predict)."""
    from experiments import run as cli

    text = open(os.path.join(ROOT, "docs", "function_systems.md")).read()
    module = next(b for b in re.findall(r"```python\n(.*?)```", text, flags=re.S) if b.startswith("# my_"))
    (command,) = re.findall(r"```bash\n(.*?)```", text, flags=re.S)
    argv = shlex.split(command.replace("\\\n", " "))[3:]
    monkeypatch.chdir(tmp_path)
    (tmp_path / "my_pendulum.py").write_text(module)
    tiny = ["--data.n_traj", "40", "--surrogate.mlp.epochs", "2", "--data.levels", "0.1", "--out", "runs"]
    tiny += ["--surrogate.sindy.libraries", "cubic_trig"]
    argv = [a if a != "d2c" else "control" for a in argv]
    assert cli.main(argv + tiny + ["--experiment.name", "control"]) == 0
    (folder,) = glob.glob("runs/*_control")
    metrics = json.load(open(os.path.join(folder, "metrics.json")))
    assert metrics["status"] in ("converged", "stalled"), metrics["status"]
    assert metrics["d2c"]["goal"]["reached"]


def test_the_changelog_leads_with_the_released_version_and_keeps_nothing_unreleased():
    """CHANGELOG.md's first section is the package's version (pyproject.toml and
    ``__version__`` agree) and no "Unreleased" section sits among the releases."""
    import mjx_surrogate

    text = open(os.path.join(ROOT, "CHANGELOG.md")).read()
    sections = re.findall(r"^## (.+)$", text, flags=re.M)
    assert sections and not any("unreleased" in s.lower() for s in sections[1:]), sections
    latest = next(s for s in sections if "unreleased" not in s.lower())
    project = open(os.path.join(ROOT, "pyproject.toml")).read()
    (pyproject,) = re.findall(r'^version = "([^"]+)"', project, re.M)
    assert latest.split()[0] == pyproject == mjx_surrogate.__version__, (latest, pyproject)
