"""Function black boxes from a config and the command line (``system.name`` lorenz, f8,
or python with ``system.entry``): bad input is one line and exit 2, runs write folders that
replay, a changed source refuses to replay; an MJCF run replays its own model copy."""

import glob
import json
import os
import textwrap

import numpy as np
import pytest

from experiments import run as cli
from mjx_surrogate.runs.config import Config, SystemConfig, TaskConfig
from mjx_surrogate.runs.resolution import resolve
from mjx_surrogate.systems import lorenz
from mjx_surrogate.systems.registry import default_config

PENDULUM = textwrap.dedent(
    """
    import numpy as np
    from mjx_surrogate.systems import from_numpy

    def step(x, u, dt=0.05):
        theta, omega = x
        omega = omega + dt * (-9.81 * np.sin(theta) - 0.1 * omega + u[0])
        return np.array([theta + dt * omega, omega])

    def make_system():
        return from_numpy(step, 2, 1, 0.05, name="user_pendulum", u_min=-5.0, u_max=5.0,
                          angle_pairs=[(0, 1)])
    """
)
TASK = "--task.preset custom --task.x0 0 0 --task.x_goal 3.14159 0 --task.T 40 --task.Q_diag 0 0"
TASK += " --task.Q_f_diag 100 100 --task.R_diag 0.01"


def _module(tmp_path, body=PENDULUM, name="user_pendulum.py"):
    path = tmp_path / name
    path.write_text(body)
    return str(path)


def _fails(argv, capsys, needle):
    assert cli.main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith(f"error: {needle}"), err
    return err


def test_registered_presets_resolve_to_the_modules_tasks():
    res = resolve(Config(system=SystemConfig(name="lorenz"), task=TaskConfig(preset="lorenz_switch")))
    want = lorenz.switch_task()
    assert res.system is resolve(res.config).system  # built once per process
    np.testing.assert_allclose(res.task.x0, want.x0)
    np.testing.assert_allclose(res.task.Q_f, want.Q_f)
    np.testing.assert_allclose(res.task.u_max, want.u_max)
    assert res.config.experiment.exact_oracle and res.config.solver.init == "zeros"
    assert res.config.system.source_sha256 is None  # the project's own module


BAD = [
    ("--system.name python", "system.entry: required"),
    ("--system.name lorenz --system.entry x.py:f", "system.entry: only valid"),
    ("--system.name lorenz --system.substeps 2", "system.substeps: a MuJoCo setting"),
    ("--system.name lorenz --system.backend native", "system.backend:"),
    ("--system.name lorenz --task.preset hold", "task.preset: 'hold'"),
    ("--system.name lorenz --task.preset pendulum_d2c", "task.preset: 'pendulum_d2c' is a task for"),
    ("--system.name lorenz --task.preset lorenz_switch --task.x0_keyframe 0", "task.x0_keyframe:"),
    ("--system.name lorenz --task.preset lorenz_switch --task.x0 1 2", "task.x0: needs 3 entries"),
    ("--system.name f8 --task.preset f8_recovery --task.u_max 0.5", "task.u_max: wider"),
    ("--system.name lorenz --task.preset lorenz_switch --solver.init hold", "solver.init: 'hold'"),
    ("--system.name lorenz --task.preset lorenz_switch --task.goals site:a:0,0,0", "task.goals:"),
]


@pytest.mark.parametrize("args,needle", BAD)
def test_bad_function_system_input_is_one_line(args, needle, tmp_path, capsys):
    _fails(args.split() + ["--out", str(tmp_path)], capsys, needle)
    assert not os.listdir(tmp_path)


STEP = "return np.array([theta + dt * omega, omega])"
ENTRY_FAILURES = [
    ("missing.py:make_system", None, "system.entry: no such file"),
    ("{m}:nothing", PENDULUM, "system.entry: '{m}' has no attribute 'nothing'"),
    ("{m}", PENDULUM, "system.entry: '{m}' is not MODULE:ATTRIBUTE"),
    (
        "{m}:make_system",
        "raise RuntimeError('no licence')",
        "system.entry: importing '{m}' raised RuntimeError",
    ),
    ("{m}:make_system", "def make_system():\n    return 3\n", "system.entry: {m}:make_system gave a int"),
    (
        "{m}:make_system",
        PENDULUM.replace(STEP, "raise OSError('disk')"),
        "system.entry: the black box's step failed",
    ),
    (
        "{m}:make_system",
        PENDULUM.replace("omega])", "omega, 0.0])"),
        "system.entry: the black box's step failed",
    ),
    (
        "{m}:make_system",
        PENDULUM.replace("omega])", "omega * np.nan])"),
        "task.x0: the black box's step returned",
    ),
    ("no_such_module_xyz:make", None, "system.entry: importing 'no_such_module_xyz' raised ModuleNotFound"),
]


@pytest.mark.parametrize("entry,body,needle", ENTRY_FAILURES)
def test_a_broken_entry_point_is_one_line_naming_it(entry, body, needle, tmp_path, capsys):
    m = _module(tmp_path, body) if body is not None else str(tmp_path / "missing.py")
    if entry.startswith("missing"):
        entry = str(tmp_path / entry)
    args = f"--system.name python --system.entry {entry.format(m=m)} {TASK} --out {tmp_path / 'runs'}"
    err = _fails(args.split(), capsys, needle.format(m=m).split(": ")[0])
    assert needle.format(m=m).split(": ", 1)[1] in err, err


@pytest.mark.slow
def test_lorenz_preset_from_the_command_line_reaches_the_oracle(tmp_path, capsys):
    assert cli.main(["lorenz_d2c", "--out", str(tmp_path), "--experiment.name", "l"]) == 0
    (folder,) = glob.glob(str(tmp_path / "*_l"))
    metrics = json.load(open(os.path.join(folder, "metrics.json")))
    assert metrics["d2c"]["goal"]["reached"] and metrics["d2c"]["status"] in ("converged", "stalled")
    assert abs(metrics["d2c_vs_exact_relative_gap"]) < 0.01


@pytest.mark.slow
def test_an_mjcf_run_replays_its_own_model_after_the_file_was_edited(tmp_path, capsys):
    xml = default_config("pendulum").xml()
    path = tmp_path / "pendulum.xml"
    path.write_text(xml)
    out = tmp_path / "runs"
    args = ["--system.name", "mjcf", "--system.mjcf_path", str(path), "--task.preset", "pendulum_d2c"]
    args += ["--experiment.kind", "d2c", "--solver.max_iter", "5", "--system.backend", "native"]
    args += ["--experiment.exact-oracle", "False", "--experiment.no-video", "--experiment.name", "m"]
    assert cli.main(args + ["--out", str(out)]) == 0
    (folder,) = glob.glob(str(out / "*_m"))
    recorded = json.load(open(os.path.join(folder, "metrics.json")))["d2c"]["cost"]
    path.write_text(xml.replace('size="0.05" mass="1"', 'size="0.05" mass="3"'))  # a heavier tip
    assert cli.main([os.path.join(folder, "config.json"), "--out", str(out)]) == 0
    (again,) = glob.glob(str(out / "*_m_replay"))
    assert json.load(open(os.path.join(again, "metrics.json")))["d2c"]["cost"] == recorded
    # the edited file itself gives another cost: the replay did not read it
    assert cli.main(args[:-1] + ["edited", "--out", str(out)]) == 0
    (edited,) = glob.glob(str(out / "*_edited"))
    assert json.load(open(os.path.join(edited, "metrics.json")))["d2c"]["cost"] != pytest.approx(recorded)


TINY = ["--data.n_traj", "40", "--surrogate.mlp.epochs", "2", "--data.levels", "0.1", "--task.T", "100"]


@pytest.mark.slow
def test_the_papers_analysis_kind_runs_on_a_function_black_box(tmp_path, capsys):
    """The Lorenz analyses (convergence, Gram conditioning, variance) with one polynomial
    library each at tiny sizes (libraries side by side: the quick reproduction's
    cartpole_analysis)."""
    analysis = ["--experiment.kind", "analysis", "--analysis.convergence_library", "poly3"]
    analysis += ["--analysis.gram_libraries", "poly2", "--analysis.variance_libraries", "poly2"]
    analysis += ["--analysis.variance_levels", "0.05"]
    analysis += [
        "--analysis.n_datasets",
        "2",
        "--analysis.gram_points",
        "64",
        "--analysis.gram_mlp_levels",
        "0.05",
    ]
    analysis += ["--analysis.convergence_sindy_levels", "0.1", "--analysis.convergence_mlp_levels", "0.05"]
    assert (
        cli.main(["lorenz_predict", *TINY, *analysis, "--out", str(tmp_path), "--experiment.name", "a"]) == 0
    )
    (folder,) = glob.glob(str(tmp_path / "*_a"))
    assert json.load(open(os.path.join(folder, "metrics.json")))["status"] in ("converged", "stalled")
    assert os.path.isfile(os.path.join(folder, "gram_spectra.png"))


FAILS_LATER = PENDULUM.replace(
    "def step(x, u, dt=0.05):\n",
    "CALLS = [0]\n\n\ndef step(x, u, dt=0.05):\n    CALLS[0] += 1\n    if CALLS[0] > 8000:\n"
    "        return np.full(2, np.nan)\n",
)


@pytest.mark.slow
def test_a_black_box_that_turns_nan_mid_solve_keeps_its_last_finite_iterate(tmp_path, capsys):
    """A host step that returns NaN after 8,000 calls (the solve takes about 15,000): the
    solve ends ``diverged`` at the iteration where it did, keeping the last finite iterate
    (its controls, its states as the clean step gives them, its cost); no gains verdict on
    NaN costs."""
    entry = _module(tmp_path, FAILS_LATER, "fails_later.py") + ":make_system"
    argv = ["--system.name", "python", "--system.entry", entry, *TASK.split(), "--experiment.kind", "d2c"]
    argv += [
        "--experiment.exact-oracle",
        "False",
        "--experiment.no-progress",
        "--out",
        str(tmp_path / "runs"),
    ]
    assert cli.main(argv) == 1  # diverged
    (folder,) = glob.glob(str(tmp_path / "runs" / "*"))
    m = json.load(open(os.path.join(folder, "metrics.json")))
    d2c = m["d2c"]
    assert m["status"] == d2c["status"] == "diverged"
    assert 1 <= d2c["last_finite_iteration"] == d2c["iterations"] - 1, d2c
    assert d2c["cost"] is not None and d2c["cost"] == d2c["cost_solver"] < d2c["goal"]["goal_cost_start"]
    assert "last finite iterate" in d2c["hint"] and "last finite iterate" in d2c["cost_source"]
    assert m["feedback"]["gains"].startswith("not judged")
    with np.load(os.path.join(folder, "arrays.npz")) as a:
        U, X = a["d2c_U"], a["d2c_X"]
    x, ref = np.zeros(2), [np.zeros(2)]
    for u in U:  # the kept controls on the step as it was before it failed, float64 NumPy
        omega = x[1] + 0.05 * (-9.81 * np.sin(x[0]) - 0.1 * x[1] + u[0])
        x = np.array([x[0] + 0.05 * omega, omega])
        ref.append(x)
    np.testing.assert_allclose(X, np.array(ref), rtol=1e-9, atol=1e-12)
    assert "hint: the black box returned non-finite states" in capsys.readouterr().out
