"""Configs and the CLI: bad input exits 2 naming the field, before any compile;
a run folder holds the full schema and replays on native MuJoCo."""

import dataclasses
import glob
import json
import os
import subprocess
import sys

import mujoco
import numpy as np
import pytest
from helpers import assert_png

from experiments import run as cli
from experiments.summary import time_line
from mjx_surrogate.errors import ConfigError
from mjx_surrogate.runs.config import Config, MPCConfig, SolverConfig, from_dict, to_dict

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

BAD = [
    (["nosuchpreset"], "CONFIG"),
    (["smoke_rollout", "--system.name", "dragon"], "system.name"),
    (["smoke_rollout", "--task.T", "0"], "task.T"),
    (["smoke_rollout", "--task.T", "-3"], "task.T"),
    (["smoke_rollout", "--task.Q_diag", "1", "2", "3"], "task.Q_diag"),
    (["smoke_rollout", "--task.R_diag", "nan"], "task.R_diag"),
    (["smoke_rollout", "--task.R_diag", "0"], "task.R"),
    (["smoke_rollout", "--task.x0", "1", "2", "3"], "task.x0"),
    (["smoke_rollout", "--task.preset", "fish_d2c"], "task.preset"),
    (["smoke_rollout", "--task.preset", "custom"], "task.x_goal"),
    (["smoke_rollout", "--task.T", "abc"], "--task.T"),
    (["smoke_rollout", "--no.such.field", "1"], "--no.such.field"),
    (["smoke_rollout", "--system.backend", "gpu"], "--system.backend"),
    (["smoke_rollout", "--sysid.sigma_x", "-1"], "sysid.sigma_x"),
    (["default", "--sysid.n_samples", "2"], "sysid.n_samples"),
    (["smoke_rollout", "--system.name", "mjcf"], "system.mjcf_path"),
    (["smoke_predict", "--surrogate.sindy.libraries", "poly3_banana"], "surrogate.sindy.libraries[0]"),
    (["smoke_predict", "--surrogate.sindy.trig_coords", "9"], "surrogate.sindy.trig_coords"),
    (["smoke_predict", "--surrogate.kinds", "sindy", "gpr"], "surrogate.kinds[1]"),
    (["smoke_d2c", "--sysid.scheme", "bogus"], "sysid.scheme"),
    (["smoke_predict", "--data.levels", "0.1", "nan"], "data.levels"),
    (["smoke_predict", "--data.test_fraction", "1.5"], "data.test_fraction"),
    (["smoke_predict", "--surrogate.mlp.batch_size", "100000"], "surrogate.mlp.batch_size"),
    (["smoke_predict", "--surrogate.mlp.checkpoints", "9"], "surrogate.mlp.checkpoints"),
    (["smoke_analysis", "--analysis.convergence_library", "foo"], "analysis.convergence_library"),
    (["smoke_analysis", "--analysis.variance_libraries", "poly3"], "analysis.variance_levels"),
    (["smoke_theory", "--analysis.theory_max_order", "20"], "analysis.theory_max_order"),
    (["smoke_rollout", "--task.goals", "site:tip"], "task.goals"),
    (["smoke_rollout", "--task.goals", "site::1,2,3"], "task.goals"),
    (["smoke_rollout", "--task.goals", "joint:tip:0,0,1"], "task.goals"),
    (["smoke_rollout", "--task.goals", "site:tip:0,1"], "task.goals"),
    (["smoke_rollout", "--task.goals", "site:tip:0,0,x"], "task.goals"),
    (["smoke_rollout", "--task.goals", "site:nosuchsite:0,0,1"], "task.goals[0].name"),
    (["smoke_mpc", "--mpc.sysid.scheme", "bogus"], "mpc.sysid.scheme"),
    (["smoke_mpc", "--mpc.realtime_speed", "0"], "mpc.realtime_speed"),
    (["smoke_mpc", "--mpc.realtime", "--mpc.controllers", "tvlqr"], "mpc.realtime"),
    (["smoke_mpc", "--mpc.sysid.scheme", "rollout", "--mpc.sysid.every", "2"], "mpc.sysid.every"),
    (["smoke_rollout", "--task.goals", "site:tip:0,0,1:velocity=1,2"], "task.goals"),
    (["smoke_rollout", "--task.goals", "site:tip:0,0,1:orbit=0.1,x"], "task.goals"),
    (["smoke_rollout", "--task.goals", "site:tip:0,0,1:orbit=0.1,0"], "task.goals[0].orbit_period"),
    (["smoke_rollout", "--task.goals", "site:tip:0,0,1:orbit=-0.1,1"], "task.goals[0].orbit_radius"),
    (["smoke_rollout", "--task.goals", "site:tip:0,0,1:orbit=0.1,1,xw"], "task.goals[0].orbit_plane"),
    (["smoke_rollout", "--task.goals", "site:tip:0,0,1:velocity=0,inf,0"], "task.goals[0].velocity"),
    (
        ["smoke_rollout", "--system.name", "mjcf", "--system.mjcf_path", "/nonexistent.xml"],
        "system.mjcf_path",
    ),
]


def test_point_goals_from_the_command_line():
    cfg, _ = cli.parse_args(
        ["default", "--task.goals", "site:tip:0.1,-0.2,0.01:0.5:1000", "body:hand:1,2,3", "--task.T", "9"]
    )
    tip, hand = cfg.task.goals
    assert (tip.kind, tip.name, tip.target, tip.weight, tip.final_weight) == (
        "site",
        "tip",
        (0.1, -0.2, 0.01),
        0.5,
        1000,
    )
    assert (hand.kind, hand.name, hand.target, hand.weight, hand.final_weight) == (
        "body",
        "hand",
        (1, 2, 3),
        0.0,
        1.0,
    )
    assert cfg.task.T == 9  # the options after the goals are read as usual
    (hand,) = cli.parse_args(["default", "--task.goals", "site:robot0:S_fftip:1,2,3:0:5"])[0].task.goals
    assert (hand.name, hand.target, hand.final_weight) == (
        "robot0:S_fftip",
        (1, 2, 3),
        5,
    )  # gymnasium-robotics names
    assert "--task.goals KIND:NAME:X,Y,Z" in cli.GOALS_HELP
    (moving,) = cli.parse_args(
        ["default", "--task.goals", "site:tip:1,2,3:0.5:2:velocity=0.1,0,-0.2:orbit=0.05,2,yz"]
    )[0].task.goals
    assert (moving.target, moving.weight, moving.final_weight, moving.velocity) == (
        (1, 2, 3),
        0.5,
        2,
        (0.1, 0, -0.2),
    )
    assert (moving.orbit_radius, moving.orbit_period, moving.orbit_plane) == (0.05, 2, "yz")


@pytest.mark.parametrize("argv,field", BAD)
def test_bad_input_exits_2_naming_the_field(argv, field, capsys, tmp_path):
    code = cli.main(argv + ["--out", str(tmp_path)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and err[0].startswith(f"error: {field}"), err
    assert not os.listdir(tmp_path)  # nothing written, nothing compiled


def test_broken_mjcf_file_via_cli(tmp_path, capsys):
    bad = tmp_path / "bad.xml"
    bad.write_text("<mujoco><worldbody><geom type='sphere'/></mujoco>")
    code = cli.main(
        [
            "smoke_rollout",
            "--system.name",
            "mjcf",
            "--system.mjcf_path",
            str(bad),
            "--out",
            str(tmp_path / "runs"),
        ]
    )
    assert code == 2
    assert capsys.readouterr().err.startswith("error: system.mjcf_path: invalid MJCF")


def test_cli_subprocess_exit_status(tmp_path):
    out = subprocess.run(
        [sys.executable, "-m", "experiments.run", "smoke_rollout", "--task.T", "0"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 2
    assert "error: task.T: horizon must be a positive integer" in out.stderr


def test_help_lists_presets_and_fields(capsys):
    with pytest.raises(SystemExit) as e:
        cli.main(["--help"])
    assert e.value.code == 0
    text = capsys.readouterr().out
    for needle in ("default", "smoke_rollout", "--task.T", "--system.backend", "--sysid.scheme"):
        assert needle in text


def test_config_json_roundtrip_and_strictness():
    cfg = cli.load_config("default")
    assert from_dict(Config, json.loads(json.dumps(to_dict(cfg)))) == cfg
    with pytest.raises(ConfigError, match="^task.bogus: unknown field"):
        from_dict(Config, {"task": {"bogus": 1}})
    with pytest.raises(ConfigError, match="^solver.max_iter: expected an integer"):
        from_dict(Config, {"solver": {"max_iter": "ten"}})


def test_config_built_in_python_has_its_choices_checked():
    """A notebook user's dataclass config gets the same one-line error as a config file."""
    import dataclasses

    from mjx_surrogate.runs.resolution import resolve

    cfg = cli.load_config("smoke_d2c")
    bad = dataclasses.replace(cfg, sysid=dataclasses.replace(cfg.sysid, scheme="bogus"))
    with pytest.raises(
        ConfigError, match="^sysid.scheme: unknown identification scheme 'bogus'; valid: .*forward_difference"
    ):
        resolve(bad)
    bad = dataclasses.replace(cfg, system=dataclasses.replace(cfg.system, backend="gpu"))
    with pytest.raises(ConfigError, match="^system.backend: got 'gpu'"):
        resolve(bad)


def _cost(cfg, X, U):
    x_goal = np.array(cfg["task"]["x_goal"])
    Q, Qf, R = (np.array(cfg["task"][k]) for k in ("Q", "Q_f", "R"))
    dx = X - x_goal
    run = 0.5 * np.einsum("ti,ij,tj->", dx[:-1], Q, dx[:-1]) + 0.5 * np.einsum("ti,ij,tj->", U, R, U)
    return run + 0.5 * dx[-1] @ Qf @ dx[-1]


@pytest.mark.slow
def test_run_folder_schema_and_native_replay(tmp_path):
    code = cli.main(["smoke_rollout", "--out", str(tmp_path), "--experiment.name", "r"])
    assert code == 0
    (path,) = glob.glob(str(tmp_path / "*_r"))
    for f in ("config.json", "model.xml", "metrics.json", "arrays.npz", "versions.json", "rollouts.png"):
        assert os.path.getsize(os.path.join(path, f)) > 0, f
    assert_png(os.path.join(path, "rollouts.png"))
    cfg = json.load(open(os.path.join(path, "config.json")))
    metrics = json.load(open(os.path.join(path, "metrics.json")))
    arrays = np.load(os.path.join(path, "arrays.npz"))
    versions = json.load(open(os.path.join(path, "versions.json")))
    assert {"python", "jax", "mujoco"} <= set(versions)
    T = cfg["task"]["T"]
    assert np.array(cfg["task"]["Q"]).shape == (2, 2) and cfg["system"]["substeps"] == 5
    # Replay NAME_U from x0 on native MuJoCo with the saved MJCF: same X, same cost.
    m = mujoco.MjModel.from_xml_string(open(os.path.join(path, "model.xml")).read())
    d = mujoco.MjData(m)
    x0 = arrays["x0"]
    d.qpos[:], d.qvel[:] = x0[: m.nq], x0[m.nq :]
    X = [x0]
    for u in arrays["nominal_U"]:
        d.ctrl[:] = u
        for _ in range(cfg["system"]["substeps"]):
            mujoco.mj_step(m, d)
        X.append(np.concatenate([d.qpos, d.qvel]))
    X = np.array(X)
    assert arrays["nominal_U"].shape == (T, 1) and arrays["nominal_X"].shape == (T + 1, 2)
    np.testing.assert_allclose(X, arrays["nominal_X"], atol=1e-5)
    assert _cost(cfg, X, arrays["nominal_U"]) == pytest.approx(
        metrics["rollouts"]["nominal"]["cost"], rel=1e-5
    )
    # The saved config replays as a config.
    assert cli.load_config(os.path.join(path, "config.json")).task.T == T


def test_runs_never_overwrite(tmp_path):
    from mjx_surrogate.runs.results import RunFolder

    a, b = RunFolder(str(tmp_path), "same"), RunFolder(str(tmp_path), "same")
    assert a.path != b.path
    a.write_json("metrics.json", {"a": 1})
    # under construction: only a hidden .partial folder exists
    assert all(
        os.path.basename(p).startswith(".")
        for p in glob.glob(str(tmp_path / "*")) + glob.glob(str(tmp_path / ".*"))
    )
    pa, pb = a.close(), b.close()
    assert pa != pb and os.path.isdir(pa) and os.path.isdir(pb)
    assert json.load(open(os.path.join(pa, "metrics.json"))) == {"a": 1}


def test_every_ilqr_parameter_is_a_solver_field_with_its_default_and_reaches_it():
    """One definition: each ILQRParams field is a SolverConfig field of the same name (no
    rename table) with the same default, and a changed value reaches the solver; the
    model strategy's settings come from the config's extension settings."""
    from mjx_surrogate.control import model_strategies as mst
    from mjx_surrogate.control.ilqr import ILQRParams
    from mjx_surrogate.runs.resolution import solver_params

    own_fields = ("record_trajectories", "model_strategy_settings")
    names = [f.name for f in dataclasses.fields(ILQRParams) if f.name not in own_fields]
    default, own = SolverConfig(), ILQRParams()
    assert {n: getattr(default, n) for n in names} == {n: getattr(own, n) for n in names}
    mst.register_model_strategy(
        "every_iteration_only", mst.StrategyKind(lambda p, f, s: mst.every_iteration())
    )
    try:
        changed = {}
        for n in names:
            v = getattr(default, n)
            changed[n] = (
                "every_iteration_only" if isinstance(v, str) else v + 1 if isinstance(v, int) else 0.375
            )
        params, _ = solver_params(Config(solver=SolverConfig(**changed)))
        assert {n: getattr(params, n) for n in names} == changed
        assert params.model_strategy_settings is None  # the strategy declares none
    finally:
        mst.MODEL_STRATEGIES.pop("every_iteration_only")


def test_every_identification_parameter_is_a_sysid_field_and_reaches_it():
    """One definition: each SysIdParams field (but the scheme's own settings) is a field of
    section sysid of the same name, and each field of mpc.sysid one of them; a changed value
    reaches the solver's SysIdParams, and mpc.sysid's reach the replans' (no rename table)."""
    from mjx_surrogate.identification.sysid import SysIdParams
    from mjx_surrogate.runs.config import MPCSysIdConfig, SysIdConfig
    from mjx_surrogate.runs.resolution import mpc_params, solver_params

    names = [f.name for f in dataclasses.fields(SysIdParams) if f.name != "settings"]
    assert sorted(names) == sorted(f.name for f in dataclasses.fields(SysIdConfig))
    assert {f.name for f in dataclasses.fields(MPCSysIdConfig)} <= set(names)
    changed = dict(
        scheme="forward_difference",
        n_samples=7,
        sigma_x=0.125,
        sigma_u=0.25,
        every=3,
        design="orthogonal",
        noise_floor=2.0,
        perturb_x0=False,
        hold_limits=True,
        significance=1.5,
        rank_tol=0.375,
    )
    assert set(changed) == set(names)
    _, sid = solver_params(Config(sysid=SysIdConfig(**changed)))
    assert {n: getattr(sid, n) for n in names} == changed
    own = dict(scheme="rollout", n_samples=9, design="gaussian", every=1)
    cfg = Config(sysid=SysIdConfig(**changed), mpc=MPCConfig(sysid=MPCSysIdConfig(**own)))
    _, replans = mpc_params(cfg)
    assert {n: getattr(replans, n) for n in names} == {**changed, **own, "significance": 1.5}


def test_a_run_folder_of_the_earlier_schema_replays_and_old_flags_say_where_they_went(tmp_path, capsys):
    """A config.json written before 0.5.0 (identification settings in solver and mpc, a
    scheme's settings under solver.<scheme>) loads as the same config; a moved flag is
    refused with one line naming its new place, exit status 2."""
    from mjx_surrogate.runs.config import MOVED, SysIdConfig, upgrade

    cfg = cli.load_config("cartpole_mpc")
    cfg = dataclasses.replace(
        cfg,
        sysid=SysIdConfig(scheme="coordinate", n_samples=5, every=2, design="orthogonal", significance=2.0),
        extensions={**cfg.extensions, "sysid.coordinate": {"step": 0.5}},
    )
    new = json.loads(json.dumps(to_dict(cfg)))
    old = json.loads(json.dumps(new))
    sysid, mpc_sysid = old.pop("sysid"), old["mpc"].pop("sysid")
    for before, after in MOVED.items():
        section, field = before.split(".")
        *where, name = after.split(".")
        old[section][field] = (sysid if where == ["sysid"] else mpc_sysid)[name]
    old["extensions"]["solver.coordinate"] = old["extensions"].pop("sysid.coordinate")
    assert (
        "sysid" not in old
        and old["solver"]["sysid_every"] == 2
        and old["mpc"]["sysid"] == "forward_difference"
    )
    assert upgrade(old) == new
    assert upgrade(new) == new
    with pytest.raises(ConfigError, match="^solver.sysid_every: moved to sysid.every in version 0.5.0"):
        from_dict(Config, {"solver": {"sysid_every": 2}})
    path = tmp_path / "config.json"
    path.write_text(json.dumps(old))
    assert cli.load_config(str(path)) == cfg  # as a replay loads it
    for flag, where in (("--solver.sysid_design", "--sysid.design"), ("--mpc.sysid", "--mpc.sysid.scheme")):
        assert cli.main(["smoke_mpc", flag, "orthogonal"]) == 2
        assert capsys.readouterr().err.strip() == f"error: {flag}: moved to {where} in version 0.5.0"


def test_the_summary_accounts_for_the_wall_time():
    metrics = {"stages": {"d2c": {"wall_s": 1.0}, "feedback": {"wall_s": 2.5}}, "wall_time_s": 4.0}
    assert time_line(metrics) == "  time: d2c 1.0 s, feedback 2.5 s, setup and files 0.5 s (total 4.0 s)"
    assert time_line({"wall_time_s": 4.0}) == ""


def test_a_derived_preset_changes_only_what_it_states():
    """Presets are data: ``derive`` takes the parent and the stated fields, nothing else,
    and refuses a field the config does not have."""
    import dataclasses

    import configs
    from mjx_surrogate.runs.config import to_dict

    parent = configs.load("cartpole_predict")
    child = configs.derive("cartpole_predict", solver={"max_iter": 7}, surrogate={"mlp.epochs": 3})
    want = dataclasses.replace(
        parent,
        solver=dataclasses.replace(parent.solver, max_iter=7),
        surrogate=dataclasses.replace(
            parent.surrogate, mlp=dataclasses.replace(parent.surrogate.mlp, epochs=3)
        ),
    )
    assert to_dict(child) == to_dict(want)
    assert configs.load("cartpole_horizon").solver == parent.solver  # a derived preset, as written
    for bad in ({"solver": {"max_iters": 7}}, {"surrogate": {"mlp.epoch": 3}}, {"solvers": {"max_iter": 7}}):
        with pytest.raises(KeyError, match="has no field"):
            configs.derive("cartpole_predict", **bad)


def test_a_goal_reads_back_from_its_own_text_and_a_configs_goals_survive_other_flags(tmp_path):
    """tyro reads --task.goals through the goal's own text form (config.goal.GOALS_ARG): each
    goal's text reads back as the goal, and a config file's goals stay as they were when
    other flags are given (tyro renders them as their default)."""
    from mjx_surrogate.runs.config import PointGoal

    goals = (
        PointGoal(name="tip", target=(0.1, -0.2, 1 / 3), weight=0.5, final_weight=1000.0),
        PointGoal(name="robot0:S_fftip", target=(1.0, 2.0, 3.0), kind="body"),
        PointGoal(
            name="hand",
            target=(0.0, 0.0, 1.0),
            velocity=(0.1, 0.0, -0.2),
            orbit_radius=0.05,
            orbit_plane="yz",
        ),
    )
    for g in goals:
        assert PointGoal.from_text(g.to_text()) == g, g.to_text()
    path = tmp_path / "with_goals.py"
    path.write_text(
        "from mjx_surrogate.runs.config import Config, PointGoal, TaskConfig\n"
        f"CONFIG = Config(task=TaskConfig(goals={goals!r}))\n"
    )
    cfg, _ = cli.parse_args([str(path), "--task.T", "7"])
    assert cfg.task.goals == goals and cfg.task.T == 7
    cfg, _ = cli.parse_args([str(path), "--task.goals", "site:tip:1,2,3"])
    assert cfg.task.goals == (PointGoal(name="tip", target=(1.0, 2.0, 3.0)),)  # replaces them all
