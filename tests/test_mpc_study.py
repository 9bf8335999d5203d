"""The "mpc" experiment end to end on its smoke preset: every controller's episodes replayed
by a plain ``mujoco.mj_step`` loop on the run folder's plant, the same noise draws for every
controller, the sampling budget matched to D2C-MPC's, the table and the figures."""

import json
import os

import mujoco
import numpy as np
import pytest

from experiments import run as cli
from tests.helpers import assert_png

CONTROLLERS = (
    "D2C-MPC",
    "oracle MPC",
    "TVLQR tracking",
    "SINDy",
    "MLP",
    "predictive sampling (S=8)",  # its own samples (smoke_mpc), beside D2C-MPC's budget
    "predictive sampling",
    "MPPI",
    "CEM",
    "SINDy cubic_trig MPC refitted online",
    "MLP MPC refitted online",
)


@pytest.fixture(scope="module")
def smoke_mpc(tmp_path_factory):
    out = tmp_path_factory.mktemp("mpc")
    assert cli.main(["smoke_mpc", "--out", str(out)]) == 0
    (folder,) = os.listdir(out)
    path = out / folder
    return path, json.loads((path / "metrics.json").read_text()), np.load(path / "arrays.npz")


def _mj_step_loop(model: mujoco.MjModel, substeps: int, x0: np.ndarray, U: np.ndarray) -> np.ndarray:
    """The independent reference: controls applied by mj_step, substeps per control step."""
    d = mujoco.MjData(model)
    X = [x0]
    for u in U:
        d.qpos[:], d.qvel[:] = X[-1][: model.nq], X[-1][model.nq :]
        d.ctrl[:] = u
        for _ in range(substeps):
            mujoco.mj_step(model, d)
        X.append(np.concatenate([d.qpos, d.qvel]))
    return np.array(X)


@pytest.mark.slow
def test_every_controllers_episodes_replay_on_the_plant_with_mj_step(smoke_mpc):
    path, m, arrays = smoke_mpc
    cfg = json.loads((path / "config.json").read_text())
    plant = mujoco.MjModel.from_binary_path(str(path / "plant_mass1.2_length1.1_damping2.mjb"))
    model = mujoco.MjModel.from_binary_path(str(path / "model.mjb"))
    assert np.allclose(plant.body_mass[1:], 1.2 * model.body_mass[1:])
    assert np.allclose(plant.body_ipos[1:], 1.1 * model.body_ipos[1:])
    assert np.allclose(plant.dof_damping, 2 * model.dof_damping)
    substeps = cfg["system"]["substeps"]
    rows = m["mpc_rows"]
    labels = {r["controller"] for r in rows}
    assert all(any(lab.startswith(c) for lab in labels) for c in CONTROLLERS), labels
    sampled = {r["controller"]: r for r in rows if r["controller"].startswith("predictive sampling")}
    assert len(sampled) == 2 and "predictive sampling (S=8)" in sampled  # budget_row: two rows
    for label, r in sampled.items():  # each counted at its own samples: S H per control step
        S = int(label.split("S=")[1].rstrip(")"))
        assert r["black_box_steps_per_control_step"] == S * cfg["mpc"]["horizon"], (label, r)
    assert len({r["arrays"]["X"] for r in rows}) == len(rows)  # each row's own arrays
    residuals = {}
    for r in rows:
        X, U = arrays[r["arrays"]["X"]], arrays[r["arrays"]["U"]]  # [E, N+1, nx], [E, N, nu]
        assert X.shape[:2] == (2, 7) and U.shape[:2] == (2, 6)
        np.testing.assert_allclose(X[:, 0], np.broadcast_to(arrays["x0"], X[:, 0].shape))
        steps = np.array(
            [
                [_mj_step_loop(plant, substeps, x, u[None])[1] for x, u in zip(Xe[:-1], Ue)]
                for Xe, Ue in zip(X, U)
            ]
        )
        residual = X[:, 1:] - steps  # the process noise each step added
        if r["process_noise"] == 0.0:
            np.testing.assert_allclose(
                X, np.array([_mj_step_loop(plant, substeps, Xe[0], Ue) for Xe, Ue in zip(X, U)]), atol=1e-10
            )
        else:
            residuals[r["controller"]] = residual
    first = next(iter(residuals.values()))
    assert 0.005 < first.std() < 0.02  # process noise 0.01
    for res in residuals.values():  # the same keys: the same draws for every controller
        np.testing.assert_allclose(res, first, atol=1e-9)


@pytest.mark.slow
def test_the_sampling_budget_matches_d2c_and_the_table_and_figures_are_written(smoke_mpc):
    path, m, _ = smoke_mpc
    rows = m["mpc_rows"]
    d2c = np.median([r["black_box_steps_per_control_step"] for r in rows if r["controller"] == "D2C-MPC"])
    ps = [r for r in rows if r["controller"].startswith("predictive sampling")]
    assert abs(ps[0]["black_box_steps_per_control_step"] - d2c) <= 5 / 2  # S H with H = 5
    assert all(r["compute_per_step_s"] > 0 and r["real_time_factor"] > 0 for r in rows)
    surrogate_stages = [v for k, v in m["stages"].items() if k.startswith("mpc/surrogates/")]
    assert len(surrogate_stages) == 8 and all(v["status"] == "done" for v in surrogate_stages)
    table = (path / "mpc_table.md").read_text()
    assert table.count("### Plant mass=1.2,length=1.1,damping=2, process noise") == 2
    # the task ends at step 8 and the episodes run 6: every plan ends at the task's end
    assert m["mpc_horizon_end"]["mode"] == "task"
    assert "Horizon: every plan ends at the task's end (step 8)" in table
    assert "TVLQR tracking" in table and all(r["plant"] == "mass=1.2,length=1.1,damping=2" for r in rows)
    fig = "mpc_cost_vs_noise_mass1.2_length1.1_damping2.png"
    for name in (fig, "mpc_cost_vs_calls.png", "mpc_trajectories.png"):
        assert_png(str(path / name))


def _d2c_and_tvlqr(out_dir):
    """The smoke preset with two controllers, written to ``out_dir``, no video."""
    import dataclasses

    cfg = cli.load_config("smoke_mpc")
    return dataclasses.replace(
        cfg,
        mpc=dataclasses.replace(cfg.mpc, controllers=("d2c", "tvlqr")),
        experiment=dataclasses.replace(cfg.experiment, out_dir=str(out_dir), video=False),
    )


def _resumed_as_uninterrupted(cfg, path: str, m0: dict) -> dict:
    """Resume the run at ``path``: it ends as the uninterrupted smoke run ``m0`` did, with
    its costs; returns the resumed run's metrics."""
    again = cli.run(cfg, "again", resume_from=path)
    m2 = json.loads(open(os.path.join(again, "metrics.json")).read())
    assert m2["status"] == m0["status"]
    costs = {(r["controller"], r["process_noise"]): r["costs"] for r in m2["mpc_rows"]}
    reference = {(r["controller"], r["process_noise"]): r["costs"] for r in m0["mpc_rows"]}
    assert len(costs) == 4
    for k, v in costs.items():
        np.testing.assert_allclose(v, reference[k], rtol=1e-9)
    return m2


@pytest.mark.slow
def test_a_failed_batch_keeps_the_finished_conditions_and_a_resumed_run_reuses_them(
    smoke_mpc, tmp_path, monkeypatch
):
    """A stage per planner and condition: the conditions finished before a failure are
    kept, and resuming runs only the others, to the same costs as an uninterrupted run."""

    from experiments import mpc_study

    _, m0, _ = smoke_mpc
    cfg = _d2c_and_tvlqr(tmp_path)
    real = mpc_study._row

    def failing(res, e, *args):
        if e.controller == "tvlqr" and e.index == 1:
            raise RuntimeError("a planted failure")
        return real(res, e, *args)

    monkeypatch.setattr(mpc_study, "_row", failing)
    path = cli.run(cfg, "first")
    m = json.loads(open(os.path.join(path, "metrics.json")).read())
    assert m["status"] == "failed"
    done = {k for k, v in m["stages"].items() if k.startswith("mpc/") and v["status"] == "done"}
    assert done == {"mpc/d2c/mpc_D2C-MPC_0", "mpc/d2c/mpc_D2C-MPC_1", "mpc/tvlqr/mpc_TVLQR_tracking_0"}

    monkeypatch.setattr(mpc_study, "_row", real)
    m2 = _resumed_as_uninterrupted(cfg, path, m0)
    resumed = {k for k, v in m2["stages"].items() if v.get("resumed")}
    assert resumed == done | {"d2c"}


@pytest.mark.slow
def test_a_stop_inside_a_batch_ends_it_and_a_resumed_run_finishes_it(smoke_mpc, tmp_path, monkeypatch):
    """A stop request seen at a control step of the second D2C-MPC batch: that batch skips
    its remaining steps and is not kept, the run ends interrupted with the first condition
    kept, and resuming runs the rest to the uninterrupted run's costs."""
    import contextlib

    from experiments import mpc_study
    from mjx_surrogate import progress

    _, m0, _ = smoke_mpc
    cfg = _d2c_and_tvlqr(tmp_path)
    real, batches, seen = progress.meter, [], []

    class StopAtStep2:
        n = 0

        def refresh(self):
            seen.append(self.n)
            if self.n >= 2:
                progress.request_stop()

    @contextlib.contextmanager
    def meter(desc, total, display=True, leave=True):
        with real(desc, total, False, leave) as pm:
            batches.extend([desc] if "D2C-MPC" in desc else [])  # not the offline solve's
            if "D2C-MPC" in desc and len(batches) == 2:
                progress._BARS[int(pm.meter_id)] = StopAtStep2()
            yield pm

    monkeypatch.setattr(mpc_study.progress, "meter", meter)
    path = cli.run(cfg, "first")
    m = json.loads(open(os.path.join(path, "metrics.json")).read())
    assert m["status"] == "interrupted" and seen == [1, 2]  # no step reported after the stop
    stages = {k: v["status"] for k, v in m["stages"].items() if k.startswith("mpc/")}
    assert stages == {"mpc/d2c/mpc_D2C-MPC_0": "done", "mpc/d2c/mpc_D2C-MPC_1": "interrupted"}

    monkeypatch.setattr(mpc_study.progress, "meter", real)
    _resumed_as_uninterrupted(cfg, path, m0)


@pytest.mark.slow
def test_the_verdict_its_cause_and_the_page(smoke_mpc):
    """The closed-loop verdict by its rule, the surrogates' one-step errors along their closed
    loops (first plant, least noise), and report.html with both videos inside."""
    from mjx_surrogate.analysis.closed_loop import closed_loop_verdict

    path, m, _ = smoke_mpc
    rows = m["mpc_rows"]
    assert all(c["judged"] for c in m["mpc_verdict"]["conditions"])  # D2C-MPC works in the smoke
    assert m["mpc_verdict"]["verdict"] == closed_loop_verdict(rows)["verdict"]
    errs = {r["controller"]: r.get("closed_loop_one_step_error") for r in rows if r["process_noise"] == 0.0}
    surrogate = {k: v for k, v in errs.items() if k.startswith(("SINDy", "MLP")) and "refitted" not in k}
    assert len(surrogate) == 2 and all(0 < v < 10 for v in surrogate.values()), errs
    assert all(v is None for k, v in errs.items() if k not in surrogate)
    assert m["mpc_verdict"]["cause"].count(" %") == 2
    assert (path / "mpc_table.md").read_text().startswith("**Closed loop, the paper's claim: ")
    text = (path / "report.html").read_text()
    assert text.count("<video ") == 2 and text.count('src="data:video/mp4;base64,') == 2
    assert m["mpc_verdict"]["text"].split(".")[0].replace("'", "&#x27;") in text


@pytest.mark.slow
def test_the_videos_show_the_stored_trajectories(smoke_mpc):
    """optimum.mp4: one frame per control step of X_star, not blank, and the pendulum in the
    frames where the stored state puts it: the centroid of the lit pixels follows
    (sin q, -cos q) (correlations beyond 0.98). mpc_episodes.mp4: the controllers side by side."""
    import imageio.v2 as imageio

    from mjx_surrogate.runs import video

    path, m, arrays = smoke_mpc
    assert m["videos"]["optimum.mp4"]["status"] == "written"
    frames = np.array(imageio.mimread(str(path / "optimum.mp4")))
    q = arrays["X_star"][:, 0]
    assert frames.shape == (len(q), 240, 320, 3)
    assert frames.std(axis=(1, 2, 3)).min() > 2  # not blank
    lit = [np.nonzero(f.mean(-1) > 40) for f in frames]
    cy, cx = np.array([ys.mean() for ys, _ in lit]), np.array([xs.mean() for _, xs in lit])
    assert np.corrcoef(cx, np.sin(q))[0, 1] > 0.98  # the camera looks along the hinge axis
    assert np.corrcoef(cy, np.cos(q))[0, 1] < -0.98  # image rows grow downwards
    episodes = np.array(imageio.mimread(str(path / "mpc_episodes.mp4")))
    order = m["mpc_video_order"]
    assert episodes.shape == (7, 240, 320 * len(order), 3) and len(order) == 11  # two refitted online
    band = episodes[:, : video.LABEL_HEIGHT].reshape(7, video.LABEL_HEIGHT, len(order), 320, 3)
    assert band.mean() < 80 and all((band[0, :, i].min(-1) > 180).sum() > 20 for i in range(len(order)))
    first = arrays[m["videos"]["mpc_episodes.mp4"]["trajectories"][0]][0]  # D2C-MPC, episode 0
    moved = np.abs(np.diff(first[:, 0])) > 0.05
    change = np.abs(np.diff(episodes[:, :, :320].astype(float), axis=0)).mean(axis=(1, 2, 3))
    assert np.all(change[moved] > 0.05)


@pytest.mark.slow
def test_the_oracle_controller_follows_exact_oracle(tmp_path):
    """Off for a user's MJCF by default (minutes of jacfwd compile): then no oracle episodes,
    and the record says why."""
    argv = ["smoke_mpc", "--mpc.controllers", "oracle", "tvlqr", "--experiment.exact_oracle", "False"]
    assert cli.main([*argv, "--experiment.no_video", "--out", str(tmp_path)]) == 0
    (path,) = tmp_path.iterdir()
    m = json.loads((path / "metrics.json").read_text())
    assert {r["controller"] for r in m["mpc_rows"]} == {"TVLQR tracking"}
    assert m["mpc_skipped"] == {"oracle": "experiment.exact_oracle is off"}


def test_the_gymnasium_preset_finds_the_installed_model_or_says_how_to_get_it(monkeypatch):
    import dataclasses
    import importlib.util

    import configs.gym_inverted_pendulum_mpc as preset
    from mjx_surrogate.errors import ConfigError
    from mjx_surrogate.runs.resolution import resolve

    cfg = cli.load_config("gym_inverted_pendulum_mpc")
    assert os.path.isfile(cfg.system.mjcf_path) and "gymnasium" in cfg.system.mjcf_path
    res = resolve(cfg)
    assert (res.system.nx, res.system.nu) == (4, 1)
    np.testing.assert_allclose([res.task.u_min[0], res.task.u_max[0]], [-3.0, 3.0])  # the model's ctrlrange
    monkeypatch.setattr(importlib.util, "find_spec", lambda name: None)
    missing = preset._asset("inverted_pendulum.xml")
    assert "pip install gymnasium" in missing
    with pytest.raises(ConfigError, match="system.mjcf_path"):
        resolve(dataclasses.replace(cfg, system=dataclasses.replace(cfg.system, mjcf_path=missing)))


def test_d2c_mpc_identifies_with_the_fewest_samples_unless_told():
    """D2C-MPC's replans: nx + nu orthogonal samples by default (the offline solve keeps the
    solver's), mpc.sysid.n_samples and mpc.sysid.design when given; a rollout scheme keeps the
    solver's samples and design."""
    import dataclasses

    from configs.smoke_mpc import CONFIG
    from mjx_surrogate.runs.config import MPCSysIdConfig
    from mjx_surrogate.runs.resolution import mpc_params, resolve, solver_params

    cfg = resolve(CONFIG).config
    _, offline = solver_params(cfg)
    params, sysid = mpc_params(cfg)
    assert (sysid.n_samples, sysid.design, params.max_iter) == (3, "orthogonal", CONFIG.mpc.max_iter)
    assert (offline.n_samples, offline.design) == (20, "gaussian")
    given = dataclasses.replace(
        CONFIG, mpc=dataclasses.replace(CONFIG.mpc, sysid=MPCSysIdConfig(n_samples=6, design="gaussian"))
    )
    assert mpc_params(resolve(given).config)[1].n_samples == 6
    assert mpc_params(resolve(given).config)[1].design == "gaussian"
    assert sysid.scheme == offline.scheme == "central_difference"  # mpc.sysid.scheme: the solver's
    forward = dataclasses.replace(
        CONFIG, mpc=dataclasses.replace(CONFIG.mpc, sysid=MPCSysIdConfig(scheme="forward_difference"))
    )
    resolved = resolve(forward).config
    assert resolved.mpc.sysid.scheme == "forward_difference"
    assert solver_params(resolved)[1].scheme == "central_difference"
    assert mpc_params(resolved)[1].scheme == "forward_difference"
    rollout = dataclasses.replace(CONFIG, sysid=dataclasses.replace(CONFIG.sysid, scheme="rollout"))
    assert (
        mpc_params(resolve(rollout).config)[1].n_samples,
        mpc_params(resolve(rollout).config)[1].design,
    ) == (
        20,
        "gaussian",
    )


def test_plans_end_at_the_tasks_end_unless_the_episodes_run_past_it():
    """mpc.horizon_end "auto" resolves to "task" where the episodes end within the task
    (smoke_mpc: 6 of its 8 steps), to "receding" where they run past it; a preset's own
    choice stays."""
    import dataclasses

    from configs.lorenz_mpc import CONFIG as LORENZ
    from configs.smoke_mpc import CONFIG
    from mjx_surrogate.runs.resolution import resolve

    def resolved(cfg, **mpc):
        return resolve(
            dataclasses.replace(cfg, mpc=dataclasses.replace(cfg.mpc, **mpc))
        ).config.mpc.horizon_end

    assert resolved(CONFIG) == "task"
    assert resolved(CONFIG, controllers=("d2c",), steps=9) == "receding"
    assert resolved(CONFIG, horizon_end="receding") == "receding"
    assert resolved(LORENZ) == "receding" and resolved(LORENZ, horizon_end="auto") == "task"


def test_a_replanning_rate_is_a_whole_number_of_control_steps():
    """mpc.replan_hz 5 on smoke_mpc's 0.1 s pendulum: a replan every 2 control steps; unset:
    every step."""
    import dataclasses

    from configs.smoke_mpc import CONFIG
    from mjx_surrogate.runs.resolution import replan_every, resolve

    cfg = resolve(dataclasses.replace(CONFIG, mpc=dataclasses.replace(CONFIG.mpc, replan_hz=5.0))).config
    assert replan_every(cfg.mpc, 0.1) == 2 and replan_every(CONFIG.mpc, 0.1) == 1
    assert replan_every(cfg.mpc, 0.03) == 0  # 6.67 steps: refused by the resolution


def test_the_first_plan_is_the_optimum_zeros_or_the_reference_controls():
    """mpc.first_plan: the offline optimum cut or extended by its last control to H steps,
    zero controls, or the task's u_ref at every step (a hold task's holding controls)."""
    from experiments.mpc_study import first_controls

    U_star = np.arange(8.0).reshape(4, 2)
    u_ref = np.array([0.5, -2.0])
    np.testing.assert_array_equal(first_controls("optimum", U_star, u_ref, 3), U_star[:3])
    np.testing.assert_array_equal(
        first_controls("optimum", U_star, u_ref, 6), np.concatenate([U_star, U_star[-1:], U_star[-1:]])
    )
    np.testing.assert_array_equal(first_controls("zeros", U_star, u_ref, 6), np.zeros((6, 2)))
    np.testing.assert_array_equal(first_controls("reference", U_star, u_ref, 5), np.tile(u_ref, (5, 1)))


@pytest.mark.slow
def test_the_noise_floor_of_the_goal_test(smoke_mpc):
    """benchmarks/noise_floor.py on smoke_mpc's pendulum swing-up: the last noise draw alone
    at the offline optimum's end fails the goal test never without noise (the optimum
    reached it) and always under noise far beyond the goal's scale; the LQR at the upright
    goal does not swing up from hanging; the disturbances of every controller's closed
    loops recovered on the run's plant; its helpers against closed forms
    (the scalar DARE's gain (sqrt(5) - 1) / 2, a linear map's own matrices)."""
    from benchmarks.noise_floor import central_differences, floor, lqr_gain

    path, metrics, _ = smoke_mpc
    assert metrics["d2c"]["goal"]["reached"]
    still = floor(str(path), 0.0, 64, 0)
    assert still["last_draw_fails"] == 0.0 and still["goal_drift"] < 1e-12  # upright: an equilibrium
    assert still["lqr_pass"] == 0.0  # the upright LQR does not swing up from hanging
    # every controller's disturbances, recovered on the changed plant's own file: none
    # without noise, the process noise's size at 0.01 (the model's step would leave the
    # plant's difference in them)
    noisy = floor(str(path), 0.01, 64, 0)
    for level, pairs in ((0.0, still["paired"]), (0.01, noisy["paired"])):
        assert len(pairs) == len(CONTROLLERS)  # one row per controller
        for p in pairs:
            assert p["plant"] == "mass=1.2,length=1.1,damping=2" and p["episodes"] == 2
            assert p["residual_rms"] < 1e-8 if level == 0 else 0.008 < p["residual_rms"] < 0.013
    assert floor(str(path), 100.0, 64, 0)["last_draw_fails"] == 1.0
    K = lqr_gain(np.eye(1), np.eye(1), np.eye(1), np.eye(1))
    np.testing.assert_allclose(K, [[(np.sqrt(5) - 1) / 2]], rtol=1e-12)
    A, B = np.array([[1.0, 0.1], [-0.3, 0.9]]), np.array([[0.0], [0.5]])
    A_fd, B_fd = central_differences(lambda x, u: A @ x + B @ u, np.array([0.2, -1.0]), np.array([0.3]))
    np.testing.assert_allclose(A_fd, A, atol=1e-9)
    np.testing.assert_allclose(B_fd, B, atol=1e-9)


def test_the_noise_floor_pairs_each_controller_with_the_lqr_on_its_own_disturbances(tmp_path):
    """benchmarks/noise_floor.paired: the disturbances handed to the LQR are the stored
    closed loop's residuals x_{n+1} - step(x_n, u_n) on the row's own plant, the injected
    draws (to round-off), at the asked noise level only, and rows whose plant has no step are
    left out; the LQR's closed loop by lqr_episodes is x_{n+1} = step(x_n, clip(u_ref -
    K (x_n - x_goal))) + W_n."""
    from benchmarks.noise_floor import lqr_episodes, paired

    A, B = np.array([[1.0, 0.1], [0.2, 0.9]]), np.array([[0.0], [0.1]])
    step = lambda x, u: A @ x + B @ u  # noqa: E731
    rng = np.random.default_rng(0)
    W = 0.01 * rng.standard_normal((3, 5, 2))
    X, U = np.zeros((3, 6, 2)), rng.standard_normal((3, 5, 1))
    X[:, 0] = [0.3, -0.1]
    for n in range(5):
        X[:, n + 1] = X[:, n] @ A.T + U[:, n] @ B.T + W[:, n]
    np.savez(tmp_path / "arrays.npz", cx=X, cu=U, other=X + 1)
    rows = [
        {"controller": "c", "plant": "model", "process_noise": 0.01, "costs": [1.0, 2.0, 3.0],
         "arrays": {"X": "cx", "U": "cu"}},
        {"controller": "c", "plant": "mass=1.2", "process_noise": 0.01, "costs": [1.0, 2.0, 3.0],
         "arrays": {"X": "other", "U": "cu"}},
    ]  # fmt: skip
    (tmp_path / "metrics.json").write_text(json.dumps({"mpc_rows": rows}))
    seen = []

    def lqr(W_given, on):
        seen.append((W_given, on))
        return np.array([2.0, 2.0, 2.0]), np.array([True, False, True])

    (p,) = paired(str(tmp_path), 0.01, {"model": step}.get, lqr)
    np.testing.assert_allclose(seen[0][0], W, atol=1e-12)
    assert seen[0][1] is step
    assert (p["plant"], p["episodes"], p["at_most_lqr"], p["lqr_passes"], p["cost_median"]) == (
        "model",
        3,
        2,
        2,
        2.0,
    )
    assert paired(str(tmp_path), 0.03, {"model": step}.get, lqr) == []
    heavier = lambda x, u: step(x, u) + 1.0  # noqa: E731  (the other row's X is X + 1)
    both = paired(str(tmp_path), 0.01, {"model": step, "mass=1.2": heavier}.get, lqr)
    assert [q["plant"] for q in both] == ["model", "mass=1.2"]
    np.testing.assert_allclose(
        seen[-1][0], (X + 1)[:, 1:] - (X[:, :-1] + 1) @ A.T - U @ B.T - 1.0, atol=1e-12
    )
    K = np.array([[0.5, 0.2]])
    Xl, Ul = lqr_episodes(step, K, X[0, 0], np.zeros(2), np.zeros(1), -np.ones(1), np.ones(1), W)
    for n in range(5):
        u = np.clip(-Xl[:, n] @ K.T, -1, 1)
        np.testing.assert_allclose(Ul[:, n], u)
        np.testing.assert_allclose(Xl[:, n + 1], Xl[:, n] @ A.T + u @ B.T + W[:, n])
