"""Extension points, used from outside the package as docs/extending.md shows: a new
identification scheme, surrogate kind, system and experiment kind are one function or
module each plus one registry entry, the first three kinds bringing settings of their own;
each then runs end to end from the command line."""

import dataclasses
import glob
import importlib.util
import json
import pathlib
import re
import sys
import types

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import mjx_surrogate as ms
from experiments import run as cli
from mjx_surrogate.control import model_strategies, planners
from mjx_surrogate.identification import sysid
from mjx_surrogate.runs import experiment_kinds
from mjx_surrogate.runs.results import load_run
from mjx_surrogate.systems import registry
from mjx_surrogate.tasks import trajectory_cost

DOC = pathlib.Path(__file__).resolve().parents[1] / "docs" / "extending.md"


def doc_module(folder: pathlib.Path) -> types.ModuleType:
    """The page's Python blocks, in order, written to one file in ``folder`` and imported
    as a user's module (registering its extensions)."""
    path = folder / "extending_doc.py"
    path.write_text("\n".join(re.findall(r"```python\n(.*?)```", DOC.read_text(), re.S)))
    spec = importlib.util.spec_from_file_location("extending_doc", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[module.__name__] = module  # dataclasses and tyro look their module up
    spec.loader.exec_module(module)
    return module


@pytest.fixture(autouse=True)
def doc(tmp_path_factory):
    module = doc_module(tmp_path_factory.mktemp("doc"))
    yield module
    sysid.SCHEMES.pop("coordinate")
    model_strategies.MODEL_STRATEGIES.pop("periodic")
    planners.PLANNERS.pop("open_loop")
    ms.surrogates.SURROGATES.pop("affine")
    experiment_kinds.EXPERIMENTS.pop("random_controls")
    registry._SYSTEMS.pop("tilted_pendulum")
    registry._TASKS.pop("tilted_up")
    registry._FUNCTION_FAMILIES.pop("gym:<id> (a gymnasium environment)")
    sys.modules.pop(module.__name__)


def test_the_page_registers_each_kind_of_extension(doc):
    declared = ms.runs.extension_settings.declared()
    assert {"sysid.coordinate", "solver.periodic", "surrogate.affine", "experiment.random_controls"} <= set(
        declared
    )
    assert declared["sysid.coordinate"] == doc.CoordinateSettings(step=1e-4)
    assert "tilted_pendulum" in registry._SYSTEMS and "tilted_up" in registry._TASKS
    assert "gym:<id> (a gymnasium environment)" in registry.system_names()


@pytest.mark.slow
def test_a_registered_scheme_drives_d2c_to_the_exact_optimum(doc):
    cfg = ms.Config(
        system=ms.SystemConfig(name="pendulum", backend="native"),
        task=ms.TaskConfig(preset="pendulum_d2c", T=20),
        sysid=ms.SysIdConfig(scheme="coordinate", n_samples=3),
        extensions={"sysid.coordinate": doc.CoordinateSettings(step=1e-4)},
    )
    cfg, system, task = ms.resolve(cfg)
    params, sid = ms.solver_params(cfg)
    U0 = jnp.zeros((task.T, 1))
    d2c = ms.solve_d2c(system, task, U0, jax.random.key(0), params, sid)
    # central differences of the black box (checked against jacfwd in tests/test_sysid.py)
    exact = ms.solve_exact(system, task, U0, params, jacobians="finite_difference")
    assert bool(d2c.converged)
    assert float(d2c.cost) == pytest.approx(float(exact.cost), rel=1e-4)


@pytest.mark.slow
def test_a_registered_scheme_and_surrogate_run_from_the_cli(tmp_path):
    code = cli.main(
        [
            "smoke_predict",
            "--out",
            str(tmp_path),
            "--sysid.scheme",
            "coordinate",
            "--sysid.coordinate.step",
            "1e-4",
            "--surrogate.kinds",
            "sindy",
            "affine",
            "--surrogate.affine.ridge",
            "0.001",
        ]
    )
    (path,) = glob.glob(str(tmp_path / "*smoke_predict"))
    metrics, arrays = load_run(path)
    assert code == 0 and metrics["status"] == "converged"
    with open(f"{path}/config.json") as f:
        extensions = json.load(f)["extensions"]
    assert extensions == {"sysid.coordinate": {"step": 1e-4}, "surrogate.affine": {"ridge": 0.001}}
    for level in ("0.1", "0.6"):
        models = metrics["results"][level]
        assert list(models)[:4] == ["SINDy cubic_trig", "SINDy quartic", "affine", "LTV"]
        assert models["affine"]["n_params"] == 8 and models["affine"]["one_step_rmse"] > 0
        assert models["affine"]["ridge"] == 0.001  # the setting reached the fit
        assert np.isfinite(arrays[f"level{0 if level == '0.1' else 1}_pred_affine"]).all()


def test_unregistered_names_are_rejected_before_any_compile(tmp_path, capsys):
    assert cli.main(["smoke_predict", "--out", str(tmp_path), "--surrogate.kinds", "gp"]) == 2
    assert capsys.readouterr().err.startswith("error: surrogate.kinds[0]: unknown surrogate kind 'gp'")


def test_a_scheme_without_a_t_test_refuses_a_significance(tmp_path, capsys):
    """``sysid.significance`` > 0 needs a scheme that applies it (``t_test``)."""
    argv = ["smoke_d2c", "--out", str(tmp_path), "--sysid.scheme", "coordinate"]
    assert cli.main(argv + ["--sysid.significance", "3"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: sysid.significance: needs a scheme with a t-test (central_diff")


def test_a_scheme_setting_reaches_its_linearize_from_the_command_line(doc):
    """``--sysid.coordinate.step`` lands in the config and in the scheme's parameters;
    the config's other extensions stay."""
    cfg, _ = cli.parse_args(["smoke_d2c", "--sysid.scheme", "coordinate", "--sysid.coordinate.step", "0.25"])
    assert cfg.extensions == {"sysid.coordinate": doc.CoordinateSettings(step=0.25)}
    assert ms.solver_params(cfg)[1].settings == doc.CoordinateSettings(step=0.25)
    assert ms.solver_params(dataclasses.replace(cfg, extensions={}))[1].settings == doc.CoordinateSettings()


@pytest.mark.parametrize(
    "args, message",
    [
        (["--sysid.coordinate.step", "-1"], "error: sysid.coordinate.step: must be > 0, got -1.0"),
        (["--sysid.coordinate.step", "abc"], "error: --sysid.coordinate.step: expects a number, got 'abc'"),
        (["--sysid.coordinate.stride", "2"], "error: --sysid.coordinate.stride: unknown field"),
        (["--sysid.coordinate.step", "nan"], "error: sysid.coordinate.step: must be a finite number"),
        (
            ["--surrogate.affine.ridge", "1"],
            "error: surrogate.affine: settings of 'affine', which this config",
        ),
        (
            ["--experiment.random_controls.n", "x"],
            "error: --experiment.random_controls.n: expects an integer",
        ),
        (
            ["--solver.model_strategy", "periodic", "--solver.periodic.period", "0"],
            "error: solver.periodic.period: must be >= 1, got 0",
        ),
        (
            ["--solver.periodic.period", "2"],
            "error: solver.periodic: settings of 'periodic', which this config",
        ),
        (["--solver.model_strategy", "nope"], "error: solver.model_strategy: unknown model strategy 'nope'"),
    ],
)
def test_bad_extension_settings_exit_2_naming_the_field(tmp_path, capsys, args, message):
    argv = ["smoke_d2c", "--out", str(tmp_path), "--sysid.scheme", "coordinate"]
    assert cli.main(argv + args) == 2
    assert capsys.readouterr().err.startswith(message)


def test_an_experiment_kind_with_its_setting_runs_from_the_command_line(tmp_path):
    argv = ["smoke_d2c", "--out", str(tmp_path), "--experiment.kind", "random_controls"]
    assert cli.main(argv + ["--experiment.random_controls.n", "3", "--system.backend", "native"]) == 0
    (path,) = glob.glob(str(tmp_path / "*smoke_d2c"))
    metrics, arrays = load_run(path)
    assert metrics["status"] == "completed" and metrics["random_controls"]["n"] == 3
    assert arrays["U"].shape == (3, 10, 1)
    # the costs are the task's on the black box's own rollouts of the stored controls
    cfg, system, task = ms.resolve(cli.load_config(f"{path}/config.json"))
    X = np.stack([np.asarray(system.rollout(task.x0, u)) for u in arrays["U"]])
    np.testing.assert_allclose(X, arrays["X"], rtol=1e-6, atol=1e-9)
    assert metrics["random_controls"]["costs"][0] == pytest.approx(
        float(trajectory_cost(task, X[0], arrays["U"][0])), rel=1e-6
    )


@pytest.mark.slow
def test_a_registered_system_solves_from_the_command_line(tmp_path):
    """A system and its task preset registered from outside; D2C reaches the task's goal
    under the tilted gravity (the registered MJCF, not the pendulum's, was built)."""
    argv = ["smoke_d2c", "--out", str(tmp_path), "--system.name", "tilted_pendulum"]
    argv += ["--task.preset", "tilted_up", "--task.T", "30", "--solver.max_iter", "200"]
    assert cli.main(argv) == 0
    (path,) = glob.glob(str(tmp_path / "*smoke_d2c"))
    metrics, arrays = load_run(path)
    with open(f"{path}/config.json") as f:
        assert json.load(f)["system"]["name"] == "tilted_pendulum"
    cfg, system, task = ms.resolve(cli.load_config(f"{path}/config.json"))
    assert np.allclose(system.mj_model.opt.gravity, [4.905, 0, -8.496])
    assert metrics["status"] == "converged"
    assert abs(float(arrays["d2c_X"][-1, 0])) < 0.05  # upright at the end


GYM_PENDULUM = ["--task.preset", "custom", "--task.x0", "3.14159", "0", "--task.x_goal", "0", "0"]
GYM_PENDULUM += [
    "--task.T",
    "100",
    "--task.Q_diag",
    "0",
    "0",
    "--task.Q_f_diag",
    "100",
    "100",
    "--task.R_diag",
    "0.01",
]


@pytest.mark.slow
def test_a_gymnasium_environment_is_a_black_box_from_the_command_line(tmp_path):
    """The page's third kind of black box, run as the page says with the defaults
    (gymnasium's Pendulum-v1 from hanging, its own step): D2C reaches the upright goal
    inside the action bounds, and the controls replayed through a fresh environment's own
    API land on the run's final state."""
    gymnasium = pytest.importorskip("gymnasium")
    argv = ["--out", str(tmp_path), "--system.name", "gym:Pendulum-v1", *GYM_PENDULUM]
    argv += ["--experiment.kind", "d2c", "--experiment.name", "gym", "--experiment.exact-oracle", "False"]
    assert cli.main(argv) == 0
    (path,) = glob.glob(str(tmp_path / "*_gym"))
    metrics, arrays = load_run(path)
    d2c = metrics["d2c"]
    assert metrics["status"] == "converged" and d2c["goal"]["reached"] and d2c["controls_within_limits"], d2c
    U, X = np.asarray(arrays["d2c_U"]), np.asarray(arrays["d2c_X"])
    assert np.all(np.abs(U) <= 2.0)  # Pendulum-v1's max_torque
    env = gymnasium.make("Pendulum-v1").unwrapped
    env.reset(seed=1)
    env.state = np.array([3.14159, 0.0])
    for u in U:
        env.step(u.astype(np.float32))
    np.testing.assert_allclose(env.state, X[-1], rtol=1e-6, atol=1e-6)


def test_a_gymnasium_mujoco_environment_steps_as_mujoco_does(doc):
    """The page's MuJoCo branch (``set_state``): one step of gym:InvertedPendulum-v5 from a
    tilted state is the environment's frame_skip of ``mujoco.mj_step`` with the control."""
    import mujoco

    pytest.importorskip("gymnasium")
    system = registry.make_function_system("gym:InvertedPendulum-v5")
    assert (system.nx, system.nu) == (4, 1) and np.allclose(system.u_max, 3.0)
    x, u = np.array([0.1, 0.2, -0.3, 0.5]), np.array([1.5])
    got = np.asarray(jax.jit(system.step)(jnp.asarray(x), jnp.asarray(u)))
    env = doc.gymnasium.make("InvertedPendulum-v5").unwrapped
    model, data = env.model, mujoco.MjData(env.model)
    data.qpos[:], data.qvel[:], data.ctrl[:] = x[:2], x[2:], u
    for _ in range(env.frame_skip):
        mujoco.mj_step(model, data)
    np.testing.assert_allclose(got, np.concatenate([data.qpos, data.qvel]), rtol=1e-12, atol=1e-12)
    assert system.dt == pytest.approx(env.dt)


@pytest.mark.parametrize(
    "env_id, message",
    [
        ("CartPole-v1", "system.name: 'CartPole-v1' acts in Discrete(2); D2C needs continuous controls"),
        ("Nope-v0", "system.name: no gymnasium environment 'Nope-v0'"),
    ],
)
def test_a_gymnasium_environment_the_kind_refuses_exits_2_naming_the_field(
    doc, tmp_path, capsys, env_id, message
):
    pytest.importorskip("gymnasium")
    argv = [
        "--out",
        str(tmp_path),
        "--system.name",
        f"gym:{env_id}",
        *GYM_PENDULUM,
        "--experiment.kind",
        "d2c",
    ]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: {message}"), err
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize(
    "extensions, message",
    [
        (
            {"solver.nope": {}},
            "extensions.solver.nope: no registered extension declares settings here; valid: ",
        ),
        ({"sysid.coordinate": {"stride": 2}}, "sysid.coordinate.stride: unknown field; valid: step"),
        ({"sysid.coordinate": {"step": "big"}}, "sysid.coordinate.step: expected a number, got 'big'"),
        (
            "affine settings",
            "sysid.coordinate: expected CoordinateSettings or a mapping",
        ),
    ],
)
def test_a_python_config_s_extension_settings_are_checked(doc, extensions, message):
    if extensions == "affine settings":  # another extension's settings class
        extensions = {"sysid.coordinate": doc.AffineSettings()}
    cfg = ms.Config(sysid=ms.SysIdConfig(scheme="coordinate"), extensions=extensions)
    with pytest.raises(ms.ConfigError) as e:
        ms.resolve(cfg)
    assert str(e.value).startswith(message)


def test_help_lists_the_settings_of_registered_extensions(doc, capsys):
    with pytest.raises(SystemExit):
        cli.parse_args(["smoke_d2c", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    for flag in (
        "--sysid.coordinate.step FLOAT",
        "--experiment.random-controls.n INT",
        "controls.scale FLOAT",
    ):
        assert flag in out  # the settings' own fields, parsed as built-in ones are


def test_the_generated_command_line_type_gives_back_the_config(doc):
    """The parser's Config type, generated from the declarations, holds every preset as it
    is: with no extension flag the parsed config equals the preset, extensions included
    (hydrax_pendulum_mpc has planners' settings as mappings); a flag replaces only its own
    extension's settings."""
    from mjx_surrogate.runs.extension_settings import declared, with_declared, without_declared

    for name in ("smoke_d2c", "hydrax_pendulum_mpc", "cartpole_control"):
        preset = cli.load_config(name)
        generated = with_declared(preset)
        assert type(generated) is not ms.Config and isinstance(generated, ms.Config)
        assert without_declared(generated, ms.Config, set()) == preset
        assert cli.parse_args([name])[0] == preset
    preset = cli.load_config("hydrax_pendulum_mpc")
    cfg, _ = cli.parse_args(["hydrax_pendulum_mpc", "--mpc.mppi.temperature", "0.5"])
    own = {**preset.extensions["mpc.mppi"], "temperature": 0.5}
    assert cfg.extensions["mpc.mppi"] == dataclasses.replace(declared()["mpc.mppi"], **own)
    assert {k: v for k, v in cfg.extensions.items() if k != "mpc.mppi"} == {
        k: v for k, v in preset.extensions.items() if k != "mpc.mppi"
    }


@pytest.mark.slow  # over 5 s: the fast tier's budget
def test_a_registered_model_strategy_with_its_setting_runs_from_the_command_line(tmp_path):
    """The page's periodic strategy: the run identifies exactly at every period-th
    iteration, its setting reaches the strategy, and the solve ends on the default's
    optimum (the pendulum's D2C preset, small)."""
    base = ["smoke_d2c", "--out", str(tmp_path), "--experiment.exact-oracle", "False"]

    def run(name, *flags):
        assert cli.main(base + ["--experiment.name", name, *flags]) == 0
        (path,) = glob.glob(str(tmp_path / f"*_{name}"))
        return load_run(path)

    m, arrays = run("periodic", "--solver.model_strategy", "periodic", "--solver.periodic.period", "3")
    n = m["d2c"]["iterations"]
    ident = np.asarray(arrays["d2c_identified"])[:n]
    np.testing.assert_array_equal(ident != 0, np.arange(n) % 3 == 0)
    default, _ = run("default")
    assert m["status"] in ("converged", "max_iter") and default["status"] == "converged"
    assert m["d2c"]["cost"] == pytest.approx(default["d2c"]["cost"], rel=1e-2)
    with open(glob.glob(str(tmp_path / "*_periodic"))[0] + "/config.json") as f:
        cfg = json.load(f)
    assert cfg["solver"]["model_strategy"] == "periodic" and cfg["extensions"] == {
        "solver.periodic": {"period": 3}
    }


@pytest.mark.slow
def test_a_registered_planner_runs_beside_d2c_mpc_from_the_command_line(tmp_path):
    """The page's open-loop planner in an MPC run: its row sits in the table and the
    verdict's input, and its episodes apply the first plan as it stands (the offline
    optimum's controls, the last one repeated past its end)."""
    argv = ["smoke_mpc", "--out", str(tmp_path), "--mpc.controllers", "open_loop", "tvlqr"]
    argv += ["--experiment.exact-oracle", "False"]
    assert cli.main(argv) == 0
    (path,) = glob.glob(str(tmp_path / "*smoke_mpc"))
    metrics, arrays = load_run(path)
    rows = [r for r in metrics["mpc_rows"] if r["controller"] == "open loop"]
    assert len(rows) == len(metrics["mpc_conditions"])
    assert all(r["black_box_steps_per_control_step"] == 0 for r in rows)
    assert rows[0]["iterations_per_replan"] is None
    with open(f"{path}/config.json") as f:
        H = json.load(f)["mpc"]["horizon"]
    U_star = np.asarray(arrays["U_star"])
    U0 = np.concatenate([U_star, np.repeat(U_star[-1:], max(0, H - len(U_star)), axis=0)])[:H]
    U = np.asarray(arrays[rows[0]["arrays"]["U"]])  # [episodes, N, nu]
    want = U0[np.minimum(np.arange(U.shape[1]), H - 1)]  # the plan shifted, its last row repeated
    np.testing.assert_allclose(U, np.broadcast_to(want, U.shape), rtol=0, atol=1e-12)
