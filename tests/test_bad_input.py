"""Every bad input found by probing the CLI as a new user: exit status 2 and one line
naming the field, before any compile, and nothing written."""

import json
import os
import re

import pytest

from experiments import run as cli

LONG = "x" * 300

CASES = [
    (["smoke_d2c", "--solver.accept_ratio", "nan"], "solver.accept_ratio"),
    (["smoke_d2c", "--solver.accept_ratio", "1.5"], "solver.accept_ratio"),
    (["smoke_predict", "--sysid.n_samples", "2"], "sysid.n_samples"),
    (["smoke_d2c", "--sysid.scheme", "rollout", "--sysid.every", "2"], "sysid.every"),
    (
        ["smoke_d2c", "--sysid.scheme", "rollout", "--sysid.design", "orthogonal"],
        "sysid.design",
    ),  # noqa: E501
    (["smoke_d2c", "--sysid.design", "sobol"], "--sysid.design"),
    (["smoke_d2c", "--solver.alpha_factor", "1"], "solver.alpha_factor"),
    (["smoke_d2c", "--solver.sysid_refine_tol", "-1"], "solver.sysid_refine_tol"),
    (["smoke_d2c", "--solver.reuse_tol", "nan"], "solver.reuse_tol"),
    (["smoke_d2c", "--solver.reuse_tol", "-0.1"], "solver.reuse_tol"),
    (["smoke_d2c", "--solver.reuse_max", "-1"], "solver.reuse_max"),
    (["smoke_d2c", "--solver.stationary_restarts", "-1"], "solver.stationary_restarts"),
    (["smoke_d2c", "--solver.stall_restarts", "-1"], "solver.stall_restarts"),
    (["smoke_d2c", "--solver.sampling_search", "-1"], "solver.sampling_search"),
    (["smoke_d2c", "--solver.mu_raise_alpha", "-0.5"], "solver.mu_raise_alpha"),
    (["smoke_d2c", "--sysid.significance", "-1"], "sysid.significance"),
    (["smoke_d2c", "--sysid.significance", "nan"], "sysid.significance"),
    (["smoke_predict", "--surrogate.mlp.stop_rel_tol", "1.5"], "surrogate.mlp.stop_rel_tol"),
    (["smoke_predict", "--surrogate.mlp.stop_window", "-1"], "surrogate.mlp.stop_window"),
    (["smoke_predict", "--surrogate.mlp.patience", "-1"], "surrogate.mlp.patience"),
    (["cartpole_predict", "--experiment.kind", "analysis"], "surrogate.mlp.patience"),
    (["smoke_predict", "--surrogate.mlp.validation_fraction", "1"], "surrogate.mlp.validation_fraction"),
    (
        ["smoke_predict", "--surrogate.mlp.patience", "5", "--surrogate.mlp.validation_fraction", "0.99"],
        "surrogate.mlp.batch_size",
    ),
    (["cartpole_horizon", "--data.n_traj", "3"], "data.n_traj"),
    (["smoke_analysis", "--sysid.n_samples", "2"], "sysid.n_samples"),
    (["smoke_d2c", "--task.x0", "1e13", "0"], "task.x0"),  # sigma_x is below the resolution at 1e13
    (["smoke_d2c", "--task.T", "1000000000"], "task.T"),
    (["smoke_d2c", "--task.T", "200000", "--sysid.n_samples", "400"], "task.T"),
    (["smoke_d2c", "--task.T", "10.5"], "--task.T"),
    (["smoke_d2c", "--experiment.seed", str(2**64)], "experiment.seed"),
    (["smoke_d2c", "--experiment.seed", "-1"], "experiment.seed"),
    (["smoke_d2c", "--experiment.name", "a/b"], "experiment.name"),
    (["smoke_d2c", "--experiment.name", ".."], "experiment.name"),
    (["smoke_d2c", "--experiment.name", LONG], "experiment.name"),
    (["smoke_d2c", "--system.timestep", "inf"], "system.timestep"),
    (["smoke_d2c", "--system.native_threads", "-2"], "system.native_threads"),
    (["smoke_d2c", "--system.control_dt", "0.013"], "system.control_dt"),
    (["smoke_d2c", "--system.control_dt", "0.02", "--system.substeps", "2"], "system.control_dt"),
    (["smoke_d2c", "--task.Q_diag", "1", "-1"], "task.Q_diag"),
    (["smoke_d2c", "--task.Q_f_diag", "1", "nan"], "task.Q_f_diag"),
    (["smoke_d2c", "--task.u_max", "5", "--system.name", "mjcf"], "system.mjcf_path"),
    (["smoke_d2c", "--task.x0_keyframe", "home"], "task.x0_keyframe"),
    (["smoke_d2c", "--task.goal_tolerance", "0"], "task.goal_tolerance"),
    (["smoke_d2c", "--out"], "--out"),
    (["smoke_d2c", "--experment.seed", "1"], "--experment.seed"),
    (["smoke_mpc", "--mpc.controllers", "d2c", "ilqg"], "mpc.controllers[1]"),
    (["smoke_mpc", "--mpc.steps", "9"], "mpc.steps"),  # tvlqr tracks the T = 8 optimum
    (["smoke_mpc", "--mpc.process_noise", "-0.1"], "mpc.process_noise[0]"),
    (["smoke_mpc", "--mpc.samples", "1"], "mpc.samples"),
    (["smoke_mpc", "--mpc.refit_weight", "nan"], "mpc.refit_weight"),
    (["smoke_mpc", "--mpc.refit_updates", "-1"], "mpc.refit_updates"),
    (["smoke_mpc", "--mpc.sysid.n_samples", "2"], "mpc.sysid.n_samples"),  # the pendulum's nx + nu = 3
    (["smoke_mpc", "--mpc.sampling_knots", "-1"], "mpc.sampling_knots"),
    (
        ["smoke_mpc", "--mpc.controllers", "d2c", "--mpc.steps", "9", "--mpc.horizon_end", "task"],
        "mpc.horizon_end",
    ),
    (["smoke_mpc", "--mpc.horizon_end", "shrink"], "--mpc.horizon_end"),
    (["smoke_mpc", "--mpc.sysid.every", "0"], "mpc.sysid.every"),
    (["smoke_mpc", "--sysid.scheme", "rollout", "--mpc.sysid.every", "2"], "mpc.sysid.every"),
    (["smoke_mpc", "--mpc.n_alphas", "0"], "mpc.n_alphas"),
    (["smoke_mpc", "--mpc.replan_hz", "3"], "mpc.replan_hz"),  # 3.33 control steps of 0.1 s
    (["smoke_mpc", "--mpc.replan_hz", "2.5"], "mpc.replan_hz"),  # 4 steps do not divide 6
    (["smoke_mpc", "--mpc.replan_hz", "-5"], "mpc.replan_hz"),
    (["smoke_mpc", "--mpc.first_plan", "random"], "--mpc.first_plan"),
    (["smoke_mpc", "--mpc.sampling_knots", "99"], "mpc.sampling_knots"),  # over the horizon
    (["smoke_mpc", "--mpc.predictive_sampling.knots", "6"], "mpc.predictive_sampling.knots"),  # H is 5
    (["smoke_mpc", "--mpc.mppi.spline", "quadratic"], "--mpc.mppi.spline"),
    (["smoke_mpc", "--mpc.mppi.temperature", "0"], "mpc.mppi.temperature"),
    (["smoke_mpc", "--mpc.cem.elites", "0"], "mpc.cem.elites"),
    (["smoke_mpc", "--mpc.mppi.budget_row"], "mpc.mppi.budget_row"),  # without its own samples
    (["smoke_mpc", "--mpc.cem.samples", "4", "--mpc.cem.elites", "5"], "mpc.cem.elites"),
    (["smoke_mpc", "--mpc.cem.explore_fraction", "1"], "mpc.cem.explore_fraction"),
    (["smoke_mpc", "--mpc.cem.iterations", "0"], "mpc.cem.iterations"),
    (["smoke_mpc", "--mpc.predictive_sampling.sigma", "nan"], "mpc.predictive_sampling.sigma"),
    (["smoke_mpc", "--mpc.ilqg.sigma", "1"], "--mpc.ilqg.sigma"),  # no such planner
    (["smoke_mpc", "--mpc.d2c.reuse_tol", "1"], "mpc.d2c.reuse_tol"),
    (["smoke_mpc", "--mpc.d2c.reuse_max", "0"], "mpc.d2c.reuse_max"),
    (
        ["smoke_mpc", "--mpc.d2c.reuse_tol", "0.02", "--mpc.sysid.scheme", "reduced"],
        "mpc.d2c.reuse_tol",
    ),
    (
        ["smoke_mpc", "--mpc.controllers", "d2c_sampling", "--mpc.d2c_sampling.samples", "1"],
        "mpc.d2c_sampling.samples",
    ),
    (["smoke_mpc", "--task.state_error", "chord"], "--task.state_error"),
    (["smoke_mpc", "--task.hessian", "newton"], "--task.hessian"),
    (["lorenz_mpc", "--mpc.plants", "mass=1.5"], "mpc.plants[0]"),  # not a keyword of Lorenz's
    (["lorenz_mpc", "--mpc.plants", "dt=0.02"], "mpc.plants[0]"),  # a plant keeps the period
    (["smoke_mpc", "--mpc.plants", "heavier"], "mpc.plants[0]"),
    (["smoke_mpc", "--mpc.plants", "mass=-1"], "mpc.plants[0]"),
    (["smoke_mpc", "--mpc.plants", "mass=inf"], "mpc.plants[0]"),
    (["smoke_mpc", "--mpc.plants", "mass=1.5,mass=2"], "mpc.plants[0]"),
    (["smoke_mpc", "--mpc.plants", "mass=1.5", "mass=1.50"], "mpc.plants"),
    (["smoke_mpc", "--mpc.plants", "viscosity=2"], "mpc.plants[0]"),
    (["cartpole_mpc", "--mpc.plants", "damping=2"], "mpc.plants[0]"),  # no joint damping
    (["smoke_d2c", "--parallel.devices", "0"], "parallel.devices"),
    (["smoke_d2c", "--parallel.devices", "4096"], "parallel.devices"),
    (["smoke_d2c", "--parallel.coordinator_address", "localhost"], "parallel.coordinator_address"),
    (["smoke_d2c", "--parallel.num_processes", "2"], "parallel.num_processes"),
    (
        [
            "smoke_d2c",
            "--parallel.distributed",
            "--parallel.num_processes",
            "2",
            "--parallel.process_id",
            "2",
        ],
        "parallel.process_id",
    ),
]


def _run(argv, capsys, tmp_path):
    has_out = any(a == "--out" or a.startswith("--out=") for a in argv)
    code = cli.main(argv + ([] if has_out else ["--out", str(tmp_path / "runs")]))
    err = capsys.readouterr().err.strip().splitlines()
    return code, err


@pytest.mark.parametrize("argv,field", CASES)
def test_bad_input_exits_2_with_one_line_naming_the_field(argv, field, capsys, tmp_path):
    code, err = _run(argv, capsys, tmp_path)
    assert code == 2, err
    assert len(err) == 1 and err[0].startswith(f"error: {field}"), err
    assert not os.path.exists(tmp_path / "runs")  # nothing written


def test_wrong_length_error_lists_the_state_labels(capsys, tmp_path):
    code, err = _run(["smoke_d2c", "--task.x0", "1", "2", "3"], capsys, tmp_path)
    assert code == 2 and "[hinge, dhinge]" in err[0], err


def test_unknown_field_names_a_close_one(capsys, tmp_path):
    code, err = _run(["smoke_d2c", "--experment.seed", "1"], capsys, tmp_path)
    assert code == 2 and "--experiment.seed" in err[0], err


def test_limits_wider_than_the_model_ctrlrange(tmp_path, capsys):
    xml = tmp_path / "m.xml"
    xml.write_text(
        '<mujoco><worldbody><body><joint name="j" type="hinge"/><geom size=".1" mass="1"/></body>'
        '</worldbody><actuator><motor joint="j" ctrlrange="-1 1"/></actuator></mujoco>'
    )
    base = ["smoke_d2c", "--system.name", "mjcf", "--system.mjcf_path", str(xml), "--task.preset", "custom"]
    task = [
        "--task.x_goal",
        "1",
        "0",
        "--task.Q_f_diag",
        "1",
        "1",
        "--task.Q_diag",
        "0",
        "0",
        "--task.R_diag",
        "1",
    ]
    code, err = _run(base + task + ["--task.u_max", "2"], capsys, tmp_path)
    assert code == 2 and err[0].startswith("error: task.u_max") and "ctrlrange" in err[0], err


def test_out_is_a_file(tmp_path, capsys):
    f = tmp_path / "file"
    f.write_text("")
    code, err = _run(["smoke_d2c", "--out", str(f / "sub")], capsys, tmp_path)
    assert code == 2 and err[0].startswith("error: experiment.out_dir"), err
    code, err = _run(["smoke_d2c", f"--out={f}"], capsys, tmp_path)
    assert code == 2 and err[0].startswith("error: experiment.out_dir"), err


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes anywhere")
def test_out_is_read_only(tmp_path, capsys):
    d = tmp_path / "ro"
    d.mkdir(mode=0o500)
    code, err = _run(["smoke_d2c", "--out", str(d)], capsys, tmp_path)
    assert code == 2 and err[0].startswith("error: experiment.out_dir"), err


@pytest.mark.parametrize(
    "body",
    [
        "raise RuntimeError('boom')\n",
        "from mjx_surrogate.runs.config import *\nCONFIG = Config(task=TaskConfig(T=10.5))\n",
        "from mjx_surrogate.runs.config import *\nCONFIG = Config(task=TaskConfig(T='10'))\n",
        "CONFIG = 3\n",
    ],
    ids=["raises", "float-T", "string-T", "not-a-config"],
)
def test_python_config_that_raises_or_has_wrong_types(body, tmp_path, capsys):
    p = tmp_path / "user.py"
    p.write_text(body)
    code, err = _run([str(p)], capsys, tmp_path)
    assert code == 2 and len(err) == 1, err
    assert err[0].startswith("error: CONFIG") or err[0].startswith("error: task.T"), err


def test_config_json_from_an_older_schema_is_reported(tmp_path, capsys):
    from mjx_surrogate.runs.config import Config, to_dict

    data = to_dict(Config())
    del data["task"]["goals"], data["surrogate"]
    p = tmp_path / "config.json"
    p.write_text(json.dumps(data))
    code, err = _run([str(p)], capsys, tmp_path)
    assert code == 2 and "missing field(s) goals" in err[0], err


def test_reproduce_cpu_devices_is_checked_before_anything_runs(tmp_path, capsys):
    import jax

    from experiments import reproduce

    jax.devices()  # in this process JAX has started: a device count can no longer be set
    for n, said in (("0", "must be >= 1"), ("2", "already started")):
        assert reproduce.main(["--cpu-devices", n, "--out", str(tmp_path)]) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith("error: --cpu-devices:") and said in err and "\n" not in err
    assert not any(tmp_path.iterdir())  # nothing ran


MESSAGES = [
    # (argv, the field the line starts with, words it must hold, words it must not)
    (["smoke_d2c", "--task.x0", "0", "1e12", "--experiment.x64"], "task.x0", ["1e+12", "1e+08"], ["x64"]),
    (["smoke_d2c", "--task.x0", "0", "1e9"], "task.x0", ["1e+09", "diverged"], []),
    (
        ["smoke_d2c", "--task.x0", "0", "1e7", "--sysid.sigma_x", "1e-9", "--experiment.x64"],
        "task.x0",
        ["float64", "sysid.sigma_x"],
        ["x64"],
    ),
    (["smoke_d2c", "--experiment.x64", "True"], "--experiment.x64", ["'True'", "no_x64"], []),
    (  # the stray value is the flag's, not the option's before it that takes the same word
        ["smoke_d2c", "--experiment.exact_oracle", "False", "--experiment.progress", "False"],
        "--experiment.progress",
        ["'False'", "no_progress"],
        ["exact_oracle"],
    ),
    (["smoke_d2c", "--task.T", "2.5"], "--task.T", ["'2.5'", "integer"], ["Got errors"]),
    (["smoke_d2c", "--solver.max_iter", "abc"], "--solver.max_iter", ["'abc'", "integer"], []),
    (["smoke_d2c", "--sysid.design", "sobol"], "--sysid.design", ["'sobol'", "orthogonal"], []),
    (["smoke_predict", "--data.levels", "0"], "data.levels", ["> 0", "got 0"], []),
    (["smoke_d2c", "--data.levels", "0.1", "-1"], "data.levels", ["got -1"], []),
    # a grid whose dense nx x nx arrays do not fit: refused before anything is compiled
    # (262144^2 float64 is 512 GiB), at the shortest horizon's bound ...
    (
        ["burgers_d2c", "--system.name", "burgers262144"],
        "system.name",
        ["nx = 262144", "T = 1", "LTV model", "GiB", "valid here: nx <="],
        [],
    ),
    # the reduced scheme and the preset's diagonal weights build no nx x nx array: what a grid
    # of 2^20 cells exceeds is the reduced scheme's T x nx arrays at the preset's horizon
    (
        ["burgers_ro_d2c", "--system.name", "burgers1048576"],
        "task.T",
        ["T x nx arrays", "T = 50", "T <="],
        ["Hessians", "LTV model", "dense"],
    ),
    # the D2C solve fits, the exact oracle's full-order one does not: refused where asked for
    # (the default is then off, with the reason in the run)
    (
        ["allen_cahn_d2c", "--system.name", "allen_cahn2d256", "--sysid.scheme", "reduced"]
        + ["--experiment.exact_oracle", "True"],
        "experiment.exact_oracle",
        ["full-order", "nx = 65536", "GiB", "valid here: false"],
        [],
    ),
    # ... and at the preset's horizon once it is read (T = 1 fits here, T = 50 does not):
    # the horizon is what to change
    (["burgers_d2c", "--system.name", "burgers8192"], "task.T", ["nx = 8192", "T = 50", "T <="], ["T = 1"]),
]


@pytest.mark.parametrize("argv,field,has,lacks", MESSAGES)
def test_messages_are_true_and_name_the_field_and_the_value(argv, field, has, lacks, capsys, tmp_path):
    code, err = _run(argv, capsys, tmp_path)
    assert code == 2 and len(err) == 1 and err[0].startswith(f"error: {field}:"), err
    assert all(w in err[0] for w in has) and not any(w in err[0] for w in lacks), err


@pytest.mark.parametrize(
    "argv",
    [
        ["default", "--task.x0", "0", "1e9"],
        ["default", "--task.x_goal", "1e12", "0"],
        ["smoke_predict", "--data.levels", "0"],
        ["default", "--out", "/dev/null/runs"],
    ],
    ids=["x0", "x_goal", "levels", "out"],
)
def test_bad_input_is_refused_before_any_compile(argv, capsys, tmp_path):
    from jax import monitoring

    compiles = []
    monitoring.register_event_duration_secs_listener(
        lambda name, *a, **k: compiles.append(name) if "backend_compile" in name else None
    )
    code, err = _run(argv, capsys, tmp_path)
    assert code == 2 and len(err) == 1, err
    assert compiles == []


def test_every_section_checks_its_own_fields_and_validation_runs_each_check(monkeypatch):
    """Validation sits beside each declaration: every section of Config (and the nested
    ones: point goals, SINDy, MLP, D2C-MPC's identification) has its own ``check``, and
    validate_static runs each one; a section whose check refuses stops it with its line."""
    import dataclasses

    from mjx_surrogate.errors import ConfigError
    from mjx_surrogate.runs.config import Config, PointGoal, TaskConfig
    from mjx_surrogate.runs.validation import validate_static

    cfg = Config(task=TaskConfig(goals=(PointGoal(name="tip", target=(0.0, 0.0, 1.0)),)))
    validate_static(cfg)
    nested = [(cfg.task.goals[0], "task.goals[0]"), (cfg.surrogate.sindy, "surrogate.sindy")]
    nested += [(cfg.surrogate.mlp, "surrogate.mlp"), (cfg.mpc.sysid, "mpc.sysid")]
    sections = [(getattr(cfg, f.name), f.name) for f in dataclasses.fields(Config) if f.name != "extensions"]
    for section, name in sections + nested:
        kind = type(section)

        def refuse(self, *args, _name=name):
            raise ConfigError(_name, "refused by its own check")

        monkeypatch.setattr(kind, "check", refuse)
        with pytest.raises(ConfigError, match=f"^{re.escape(name)}: refused by its own check$"):
            validate_static(cfg)
        monkeypatch.undo()
