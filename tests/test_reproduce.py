"""`python -m experiments.reproduce --quick`: every experiment, every figure, the report;
and resuming skips finished experiments."""

import glob
import json
import os
import re

import jax.numpy as jnp
import mujoco
import numpy as np
import pytest
from helpers import assert_png

from experiments import reproduce
from experiments.run import load_config
from mjx_surrogate.runs.config import Config, from_dict
from mjx_surrogate.runs.resolution import resolve
from mjx_surrogate.runs.results import load_run
from mjx_surrogate.runs.validation import validate_static
from mjx_surrogate.systems.plant import parse_plant, plant_label, plant_slug
from mjx_surrogate.systems.registry import is_function_system
from mjx_surrogate.tasks import trajectory_cost

FIGURES = {
    "pendulum_predict": ["predict_10pct.png", "predict_60pct.png", "locality.png"],
    "cartpole_predict": ["predict_10pct.png", "predict_60pct.png", "locality.png"],
    "fish_predict": ["predict_5pct.png", "predict_30pct.png", "locality.png"],
    "cartpole_analysis": [
        "convergence_sindy_10pct.png",
        "convergence_sindy_100pct.png",
        "convergence_mlp_5pct.png",
        "convergence_mlp_25pct.png",
        "gram_spectra.png",
        "variance_projections.png",
        "mlp_descent_directions.png",
    ],
    "theory": ["theory_variance_sigma1.png", "theory_condition_sigma1.png"],
    "cartpole_control": ["ltv_trajectory_evolution.png", "surrogate_controls.png"],
    "pendulum_control": ["ltv_trajectory_evolution.png", "surrogate_controls.png"],
    "fish_control": ["ltv_trajectory_evolution.png", "surrogate_controls.png"],
    "cartpole_horizon": ["horizon.png"],
    "swimmer_horizon": ["horizon.png"],
    "swimmer15_d2c": ["cost_history.png", "trajectory_evolution.png", "cost_vs_simulations.png"],
    "burgers_ro_d2c": ["cost_history.png", "cost_vs_simulations.png"],
    "burgers_predict": ["predict_5pct.png", "predict_60pct.png", "locality.png"],
    **{
        name: ["mpc_cost_vs_calls.png", "mpc_trajectories.png"]
        for name in ("pendulum_mpc", "cartpole_mpc", "lorenz_mpc", "gym_inverted_pendulum_mpc")
    },
}


# The suite's 10-minute budget on 2 cores holds every kind of study and of system, not all 17
# experiments (the 8 left out took about 100 s): MJCF models run natively (the pendulum, the
# cartpole, the 15-link swimmer), a PDE (Burgers) and a function system (Lorenz). The other
# presets differ from these in their system and settings only: their quick configurations
# resolve below, their systems are solved in their own tests (the closed loop on MJCF
# plants in tests/test_mpc_study.py), and the report must say "not measured" for them.
IN_SUITE = (
    "pendulum_predict",
    "cartpole_analysis",
    "theory",
    "cartpole_control",
    "cartpole_horizon",
    "swimmer15_d2c",
    "burgers_ro_d2c",
    "burgers_predict",
    "lorenz_mpc",
)


def test_every_preset_of_the_reproduction_resolves_at_its_quick_size():
    """All 17 experiments, as ``--quick`` runs them: the configuration validates and
    resolves to its system and task (nothing compiled)."""
    assert set(FIGURES) == set(reproduce.EXPERIMENTS) and set(IN_SUITE) < set(FIGURES)
    for name in reproduce.EXPERIMENTS:
        cfg = reproduce.quick(load_config(name), name)
        validate_static(cfg)
        res = resolve(cfg)
        assert cfg.task.T in (None, res.task.T) and res.task.T > 0 and res.system.nx > 0, name
        if not is_function_system(cfg.system.name):
            assert res.system.backend == "native", name


@pytest.mark.slow
def test_quick_reproduction_produces_its_experiments_figures_and_resumes(tmp_path, capsys, monkeypatch):
    """``reproduce --quick --only IN_SUITE``: each experiment kind's outputs end to end
    (predict, analysis, control, the PDE presets, closed loop); one sweep serves them all."""
    import contextlib

    from mjx_surrogate import progress

    meters, original = {}, progress.steps

    @contextlib.contextmanager
    def recording(desc, total, display=True, **kw):
        with original(desc, total, display, **kw) as meter:
            yield meter
        meters[desc] = (meter.done + 1, meter.total)

    monkeypatch.setattr(progress, "steps", recording)
    out, report = tmp_path / "runs", tmp_path / "report.md"
    only = ["--only", *IN_SUITE]
    assert reproduce.main(["--quick", "--out", str(out), "--report", str(report), *only]) == 0
    assert_each_kinds_outputs(str(out), meters)
    for name, files in FIGURES.items():
        if name not in IN_SUITE:
            assert reproduce.finished(str(out), name) is None, name
            continue
        folder = reproduce.finished(str(out), name)
        assert folder, name
        for f in files:
            assert_png(os.path.join(folder, f))
    text = report.read_text()
    for section in (
        "Fig. LTV",
        "SINDy convergence",
        "MLP convergence",
        "Fig. IllCond_SINDY",
        "Fig. IllCond MLP",
        "Fig. Variance_SINDY",
        "Fig. Variance MLP",
        "Fig. control",
        "Pendulum to upright",
        "Cartpole swing-up: open-loop against closed-loop identification",
        "D2C on the 15-link swimmer",
        "convergence test of `configs/cartpole_analysis.py`",
        "### The Hermite basis's variance formula",  # one theory section per printed formula
        "### The conditioning estimate",
        "### The LTV Gram matrix and its variance",  # the analysis stage ltv
        "### The sampling distribution and the LTV estimate",
        "MLP trained 2, 2 epochs; MLP 2 epochs trained 2, 2 epochs (by level)",  # quick: 2 epochs
        "**Code: commit `",
        "Locality (docs/method.md): median relative spread",
        "Beyond the paper: a PDE",
        "Reduced-order D2C on the viscous Burgers equation",
        "The paper's prediction study on the Burgers equation",
        "Beyond the paper: closed loop",
        "SINDy-MPC's published task and training length",
        "**Across the systems:**",
    ):
        assert section in text, section
    verdicts = ("held", "did not hold", "held in part", "inconclusive")
    for name in IN_SUITE:
        if name.endswith("_mpc"):  # the closed-loop verdict by its rule, its cost figure per plant
            folder, m = _metrics(str(out), name)
            assert m["mpc_verdict"]["verdict"] in verdicts, (name, m["mpc_verdict"])
            assert f"**Claim:** **{m['mpc_verdict']['verdict']}**" in text
            plant = m["mpc_conditions"][0]["plant"]  # the quick run keeps the last plant
            assert plant == plant_label(parse_plant(load_config(name).mpc.plants[-1]))
            assert_png(os.path.join(folder, f"mpc_cost_vs_noise_{plant_slug(parse_plant(plant))}.png"))
    # the theory: one verdict per printed formula, as its own numbers decide (only the
    # monomial formula holds; tests/test_report_rules.py turns each with contradicting data)
    part = text[text.index("## The theory, numerically") :]
    claims = [ln for ln in part[: part.index("\n## ", 1)].splitlines() if ln.startswith("**Claim:**")]
    said = [c.split("**")[3] for c in claims]
    assert said == ["held", "did not hold", "did not hold", "did not hold"], claims
    for link in re.findall(r"\]\(([^)]+\.png)\)", text):
        assert os.path.exists(tmp_path / link), link
    # the presets left out: their claims not measured, never a verdict from no data
    left_out = [n for n in reproduce.EXPERIMENTS if n not in IN_SUITE]
    left_mpc = [n for n in left_out if n.endswith("_mpc")]  # every MPC preset but Lorenz's
    assert f"**Across the systems:** not measured on {', '.join(left_mpc)};" in text
    assert text.count("**Claim:** **not measured**") == len(left_out)  # nothing run is unmeasured
    capsys.readouterr()
    assert reproduce.main(["--quick", "--out", str(out), "--report", str(report), *only]) == 0
    assert capsys.readouterr().out.count("done already") == len(IN_SUITE)
    # a run that was killed after its first stage resumes from that stage
    theory = reproduce.finished(str(out), "theory")
    mpath = os.path.join(theory, "metrics.json")
    m = json.load(open(mpath))
    original = m["by_sigma"]
    first, second = list(m["stages"])
    del m["stages"][second]
    m["status"] = "killed"
    json.dump(m, open(mpath, "w"))
    assert reproduce.main(["--quick", "--out", str(out), "--report", str(report), "--only", "theory"]) == 0
    assert "resuming the stages" in capsys.readouterr().out
    resumed = json.load(open(os.path.join(reproduce.finished(str(out), "theory"), "metrics.json")))
    assert resumed["status"] == "completed"
    assert resumed["stages"][first].get("resumed") is True
    assert not resumed["stages"][second].get("resumed")
    assert resumed["by_sigma"] == original  # same seed-derived draws: the same numbers
    assert_every_optimum_replays_natively(out)


def _metrics(out: str, name: str) -> tuple[str, dict]:
    folder = reproduce.finished(out, name)
    return folder, json.load(open(os.path.join(folder, "metrics.json")))


def assert_each_kinds_outputs(out: str, meters: dict) -> None:
    """What each experiment kind writes, checked on the sweep's folders."""
    # predict: figures, table, every model scored at every level, LTV good near its trajectory
    folder, m = _metrics(out, "pendulum_predict")
    files = set(os.listdir(folder))
    assert {"one_step_rmse_vs_level.png", "multi_step_median_vs_level.png", "rmse_table.md"} <= files
    assert m["status"] == "converged" and m["optimum"]["converged"]
    for level in ("0.1", "0.6"):
        rows = {k: v for k, v in m["results"][level].items() if not k.startswith("_")}
        assert {"MLP", "LTV"} <= set(rows) and any(k.startswith("SINDy") for k in rows), rows
        assert all(v["one_step_rmse"] is not None for v in rows.values())
    assert m["results"]["0.1"]["LTV"]["multi_step_median"] < 0.1
    assert "| 10 |" in open(os.path.join(folder, "rmse_table.md")).read()

    # analysis: every stage's meter ran through, conditioning ordered, variance recorded
    for desc in ("analysis: model convergence", "analysis: Gram spectra", "analysis: variance"):
        done, total = meters[desc]
        assert done == total > 0, (desc, meters[desc])
    folder, m = _metrics(out, "cartpole_analysis")
    assert "analysis_table.md" in os.listdir(folder) and m["status"] == "converged"
    quartic, cubic = m["ill_conditioning"]["SINDy quartic 5%"], m["ill_conditioning"]["SINDy cubic_trig 5%"]
    assert quartic["precision"] == "float64" and quartic["condition"] > cubic["condition"] > 1e3
    assert set(m["variance"]) >= {"SINDy cubic 5%", "SINDy quartic_trig 15%", "MLP 5% epoch 0"}
    for row in m["convergence"].values():  # an effect relative to the state, with its interval
        lo, hi = row["relative_spread_interval"]
        assert 0 <= lo <= hi and row["relative_spread"] >= 0, row
    for k, v in m["ill_conditioning"].items():  # the MLP's Gram apart from its null space
        if k.startswith("MLP"):
            assert v["null_space"] >= v["hidden_unit_symmetries"] > 0 and np.isfinite(
                v["condition_of_the_rest"]
            ), v

    # control: every surrogate controller run on the black box; none beats the optimum
    for name in ("cartpole_control",):  # pendulum_control: the same kind, left to the full run
        folder, m = _metrics(out, name)
        rows = m["surrogate_rows"]
        assert {r["model"] for r in rows} >= {"MLP"} and len(rows) == 4, rows
        assert sorted(r["seed"] for r in rows) == [0, 0, 1, 1]  # two seeds, fitted at once
        assert "Over the seeds" in open(os.path.join(folder, "control_table.md")).read()
        assert all("true_cost_open" in r and "true_cost_closed" in r for r in rows)
        finite = [r["true_cost_over_d2c"] for r in rows if r["true_cost_over_d2c"] is not None]
        assert finite and min(finite) > 0.99, (name, finite)
        assert "control_table.md" in os.listdir(folder)

    # RO-D2C on Burgers (32 cells, T 50, 32 samples): the jacfwd oracle's cost, the
    # basis's rank per t, every black-box step counted
    folder, m = _metrics(out, "burgers_ro_d2c")
    cfg = json.load(open(os.path.join(folder, "config.json")))
    T, n = cfg["task"]["T"], cfg["sysid"]["n_samples"]
    assert cfg["sysid"]["scheme"] == "reduced" and cfg["system"]["name"] == "burgers32"
    assert m["d2c"]["status"] == "converged" and abs(m["d2c_vs_exact_relative_gap"]) < 1e-3
    ranks = m["ltv_relative_error"]["basis_rank"]
    assert len(ranks) == T + 1 and ranks[0] == 0 and 8 <= max(ranks) <= n
    assert m["ltv_relative_error"]["max"] < 1e-6
    per_iteration = n * T + 2 * (n + 8) * T + 8 * T  # snapshots, one-step samples, line search
    assert T + per_iteration <= m["d2c"]["simulated_steps"] <= T + m["d2c"]["iterations"] * per_iteration

    # the prediction study on Burgers: every model predicts, POD records its energy
    _, m = _metrics(out, "burgers_predict")
    res = m["results"]["0.05"]
    assert {"SINDy poly2", "POD8-SINDy poly1", "POD8-SINDy poly2", "MLP", "LTV", "LTV reduced"} <= set(res)
    assert 0.9 < res["POD8-SINDy poly2"]["pod_energy"] <= 1.0
    reduced = res["LTV reduced"]["multi_step_median"]
    assert np.isfinite(reduced) and reduced < 1e-2


def _solves(metrics: dict):
    """Every solve summary in a metrics tree that names its arrays."""
    for v in metrics.values():
        if isinstance(v, dict):
            if "arrays" in v.get("native_float64", {}):
                yield v
            else:
                yield from _solves(v)


def _native_closed_loop(model, substeps, x0, U, X, K, lo, hi):
    """u_t = clip(U_t + K_t (x_t - X_t)), mj_step in float64, x = [qpos, qvel, act]."""
    d = mujoco.MjData(model)
    nq, nv = model.nq, model.nv
    d.qpos[:], d.qvel[:], d.act[:] = x0[:nq], x0[nq : nq + nv], x0[nq + nv :]
    xs, us = [np.array(x0, np.float64)], []
    for t in range(U.shape[0]):
        us.append(np.clip(U[t] + K[t] @ (xs[-1] - X[t]), lo, hi))
        d.ctrl[:] = us[-1]
        for _ in range(substeps):
            mujoco.mj_step(model, d)
        xs.append(np.concatenate([d.qpos, d.qvel, d.act]))
    return np.array(xs), np.array(us)


def assert_every_optimum_replays_natively(out):
    """Every optimum in every run folder, replayed from the folder alone (model.mjb, x0,
    NAME_U/X/K) on native MuJoCo in float64 in the mode its metrics name, costs within 1 %
    of the reported cost; every surrogate-based controller of a control run, open loop
    and closed loop, within 1 % of its reported black-box cost (or, if that blew up past
    100x D2C's, blowing up too)."""
    checked = surrogate_checked = 0
    for folder in sorted(glob.glob(os.path.join(out, "*", "metrics.json"))):
        folder = os.path.dirname(folder)
        metrics, arrays = load_run(folder)
        cfg = from_dict(Config, json.load(open(os.path.join(folder, "config.json"))))
        if is_function_system(cfg.system.name):
            continue  # no MuJoCo model: a function's runs replay by their config (test_function_cli)
        task = resolve(cfg).task
        model = mujoco.MjModel.from_binary_path(os.path.join(folder, "model.mjb"))
        for solve in _solves(metrics):
            native = solve["native_float64"]
            assert native["judged_by"] == "closed_loop"
            U, X, K = (arrays[native["arrays"][k]] for k in "UXK")
            lim = np.asarray(task.u_min), np.asarray(task.u_max)
            xs, us = _native_closed_loop(model, cfg.system.substeps, arrays["x0"], U, X, K, *lim)
            J = float(trajectory_cost(task, jnp.asarray(xs), jnp.asarray(us)))
            assert J == pytest.approx(solve["cost"], rel=1e-2), (folder, native["arrays"])
            assert J == pytest.approx(native["closed_loop"], rel=1e-6)
            checked += 1
        for row in metrics.get("surrogate_rows", []):  # iLQR on a surrogate, on the black box
            U, X, K = (arrays[row["arrays"][k]] for k in "UXK")
            lim = np.asarray(task.u_min), np.asarray(task.u_max)
            open_loop = (np.zeros_like(X), 0 * K)  # U alone, whatever the surrogate's nominal
            for (Xn, gains), reported in (
                (open_loop, row["true_cost_open"]),
                ((X, K), row["true_cost_closed"]),
            ):
                if reported is None:  # diverged on the black box
                    continue
                xs, us = _native_closed_loop(model, cfg.system.substeps, arrays["x0"], U, Xn, gains, *lim)
                J = float(trajectory_cost(task, jnp.asarray(xs), jnp.asarray(us)))
                if reported > 100 * metrics["d2c"]["cost"]:
                    # blown up (poles spinning at 1e4 rad/s): round-off decides the digits,
                    # so the replay is checked to blow up as well, not to the same cost
                    assert J > 100 * metrics["d2c"]["cost"], (folder, row["model"], J)
                    continue
                assert J == pytest.approx(reported, rel=1e-2), (folder, row["model"], row["level"])
                surrogate_checked += 1
    assert checked >= 5, checked  # the optimum of every predict, analysis and control run
    assert surrogate_checked >= 1, surrogate_checked  # cartpole_control: its finite replays


def test_an_experiments_folders_are_its_own(tmp_path):
    """pendulum_mpc's run folders are not gym_inverted_pendulum_mpc's, whose name ends
    with it (the report once showed the gymnasium run under the pendulum)."""
    for n in ("20261126-100000_pendulum_mpc", "20261126-110000_gym_inverted_pendulum_mpc"):
        (tmp_path / n).mkdir()
        (tmp_path / n / "metrics.json").write_text(json.dumps({"status": "converged"}))
    (tmp_path / "20261126-120000_pendulum_mpc_1").mkdir()  # a second run in the same second
    (tmp_path / "20261126-120000_pendulum_mpc_1" / "metrics.json").write_text('{"status": "failed"}')
    assert reproduce.finished(str(tmp_path), "pendulum_mpc").endswith("100000_pendulum_mpc")
    assert reproduce.unfinished(str(tmp_path), "pendulum_mpc").endswith("120000_pendulum_mpc_1")
    assert reproduce.finished(str(tmp_path), "gym_inverted_pendulum_mpc").endswith(
        "_gym_inverted_pendulum_mpc"
    )
