"""Defaults derived from the model: hold controls, the hold task, distinct starts, and the
command line and the API agreeing on one config."""

import glob

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from mjx_surrogate.runs import model_defaults, pipeline
from mjx_surrogate.runs.config import (
    Config,
    ExperimentConfig,
    SolverConfig,
    SysIdConfig,
    SystemConfig,
    TaskConfig,
)
from mjx_surrogate.runs.resolution import resolve

ARM = """
<mujoco>
  <option timestep="0.01"/>
  <worldbody>
    <body name="upper" pos="0 0 1">
      <joint name="shoulder" type="hinge" axis="0 1 0" damping="0.1"/>
      <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.04" mass="1.5"/>
      <body name="fore" pos="0.4 0 0">
        <joint name="elbow" type="hinge" axis="0 1 0" springref="0.3" stiffness="2"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="0.8"/>
        <site name="tip" pos="0.3 0 0"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    {actuators}
  </actuator>
  <keyframe><key name="bent" qpos="0.4 -0.7"/></keyframe>
</mujoco>
"""
MOTORS = (
    '<motor joint="shoulder" gear="2" ctrlrange="-20 20"/><motor joint="elbow" gear="1" ctrlrange="-20 20"/>'
)
SERVOS = (
    '<position joint="shoulder" kp="200" ctrlrange="-3 3"/>'
    '<position joint="elbow" kp="100" kv="2" ctrlrange="-3 3" forcerange="-50 50"/>'
)


def _model(actuators: str) -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(ARM.format(actuators=actuators))


def _qacc(m, x, u) -> np.ndarray:
    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:], d.ctrl[:] = x[: m.nq], x[m.nq :], u
    mujoco.mj_forward(m, d)
    return d.qacc.copy()


@pytest.mark.parametrize("actuators", [MOTORS, SERVOS], ids=["motors", "position servos"])
def test_hold_controls_hold_the_state_still(actuators):
    m = _model(actuators)
    x = np.concatenate([m.key_qpos[0], np.zeros(m.nv)])
    lo, hi = m.actuator_ctrlrange.T
    u = model_defaults.hold_controls(m, x, lo, hi)
    assert np.all(np.abs(_qacc(m, x, u)) < 1e-6), _qacc(m, x, u)
    assert np.abs(_qacc(m, x, np.zeros(m.nu))).max() > 1.0  # zero controls do not hold it
    if actuators == MOTORS:  # closed form: gear * u = gravity + Coriolis - springs - damping
        d = mujoco.MjData(m)
        d.qpos[:] = x[: m.nq]
        mujoco.mj_forward(m, d)
        want = (d.qfrc_bias - d.qfrc_passive) / np.array([2.0, 1.0])
        np.testing.assert_allclose(u, want, rtol=1e-6, atol=1e-9)


def test_hold_controls_respect_limits_and_leave_unactuated_joints_alone():
    m = _model('<motor joint="shoulder" gear="1" ctrlrange="-1 1"/><motor joint="elbow" ctrlrange="-20 20"/>')
    x = np.concatenate([m.key_qpos[0], np.zeros(m.nv)])
    lo, hi = m.actuator_ctrlrange.T
    u = model_defaults.hold_controls(m, x, lo, hi)
    assert u[0] == pytest.approx(1.0) or u[0] == pytest.approx(-1.0)  # the shoulder saturates
    assert np.all(u >= lo) and np.all(u <= hi)
    # one motor on the elbow only: no control moves the shoulder, the elbow is held
    m1 = _model('<motor joint="elbow" ctrlrange="-20 20"/>')
    u1 = model_defaults.hold_controls(m1, x, *m1.actuator_ctrlrange.T)
    assert np.isfinite(u1).all() and u1.shape == (1,)


def _hold_cfg(path, **solver) -> Config:
    return Config(
        system=SystemConfig(name="mjcf", mjcf_path=path, backend="native"),
        task=TaskConfig(preset="hold", x0_keyframe="bent"),
        solver=SolverConfig(max_iter=3, **solver),
        experiment=ExperimentConfig(progress=False),
    )


def test_stall_restarts_default_to_four_on_a_users_model_and_off_on_the_papers_systems(tmp_path):
    """A user's MJCF model gets 4 restarts after a stalled solve, a registered system none
    (the paper's single start); a value in the config is kept as given."""
    path = str(tmp_path / "arm.xml")
    open(path, "w").write(ARM.format(actuators=SERVOS))
    assert resolve(_hold_cfg(path))[0].solver.stall_restarts == model_defaults.USER_STALL_RESTARTS == 4
    assert resolve(_hold_cfg(path, stall_restarts=0))[0].solver.stall_restarts == 0
    registered = Config(system=SystemConfig(name="pendulum"), experiment=ExperimentConfig(progress=False))
    assert resolve(registered)[0].solver.stall_restarts == 0
    assert model_defaults.default_stall_restarts("python") == 4


@pytest.mark.slow
def test_the_hold_task_starts_at_rest_and_multi_starts_are_distinct(tmp_path):
    path = str(tmp_path / "arm.xml")
    open(path, "w").write(ARM.format(actuators=SERVOS))
    res = resolve(_hold_cfg(path, n_starts=3))
    cfg, system, task = res
    assert cfg.task.T == model_defaults.HOLD_T and cfg.solver.init == "hold"
    np.testing.assert_array_equal(np.asarray(task.x_goal), np.asarray(task.x0))
    U0s = pipeline.start_controls(system, task, "hold", 0.1, jax.random.key(0), 3)
    hold = model_defaults.hold_controls(system.mj_model, np.asarray(task.x0), task.u_min, task.u_max)
    np.testing.assert_allclose(np.asarray(U0s[0]), np.broadcast_to(hold, (task.T, system.nu)))
    assert not np.allclose(U0s[1], U0s[0]) and not np.allclose(U0s[2], U0s[1])
    lo, hi = np.asarray(task.u_min), np.asarray(task.u_max)
    assert np.all(np.asarray(U0s) >= lo) and np.all(np.asarray(U0s) <= hi)
    np.testing.assert_array_equal(np.asarray(task.u_ref), hold)  # R pulls towards holding
    # Held from the start: the first cost is tiny, and the goal test means something.
    timed, U0, costs = pipeline.solve_config(res)[:3]
    assert costs is not None and len(costs) == 3
    X, J = pipeline.black_box_trajectory(system, task, timed.out.U)
    assert pipeline.goal_test(task, X, cfg.task.goal_tolerance)["reached"]


@pytest.mark.slow
def test_the_command_line_and_the_api_give_the_same_solve(tmp_path):
    from experiments import run as cli
    from mjx_surrogate.runs.results import load_run

    path = str(tmp_path / "arm.xml")
    open(path, "w").write(ARM.format(actuators=MOTORS))
    argv = ["default", "--system.name", "mjcf", "--system.mjcf_path", path, "--task.preset", "hold"]
    argv += ["--task.x0_keyframe", "bent", "--solver.max_iter", "3", "--experiment.seed", "7"]
    assert cli.main(argv + ["--out", str(tmp_path / "runs"), "--experiment.no-progress"]) == 0
    (folder,) = glob.glob(str(tmp_path / "runs" / "*_default"))
    metrics, arrays = load_run(folder)
    cfg = Config(
        system=SystemConfig(name="mjcf", mjcf_path=path),
        task=TaskConfig(preset="hold", x0_keyframe="bent"),
        solver=SolverConfig(max_iter=3),
        experiment=ExperimentConfig(seed=7),
    )
    timed, U0 = pipeline.solve_config(resolve(cfg))[:2]
    np.testing.assert_array_equal(np.asarray(timed.out.U), arrays["d2c_U"])
    assert float(timed.out.cost) == metrics["d2c"]["cost_solver"]
    # The run says whether its gains are to be used, true of its own noise trials.
    fb = metrics["feedback"]
    worse = [
        lv
        for lv, c, o in zip(fb["noise_levels"], fb["closed_loop_median"], fb["open_loop_median"])
        if lv > 0 and c > o
    ]
    assert (fb["gains"] == "help") == (not worse), fb
    closed, opened = (
        np.median(arrays["feedback_closed_costs"], 1),
        np.median(arrays["feedback_open_costs"], 1),
    )
    np.testing.assert_allclose(closed, fb["closed_loop_median"])
    np.testing.assert_allclose(opened, fb["open_loop_median"])


def test_gains_verdict_names_the_levels_where_feedback_hurts():
    assert pipeline.gains_verdict([0.0, 0.01, 0.05], [1.0, 2.0, 3.0], [1.0, 2.5, 3.5]) == "help"
    bad = pipeline.gains_verdict([0.0, 0.01, 0.05], [1.0, 2.0, 4.0], [1.0, 2.5, 3.5])
    assert bad.startswith("do not use") and "[0.05]" in bad
    assert "do not use" in pipeline.gains_verdict([0.01], [float("nan")], [1.0])


def test_gains_verdict_says_no_effect_or_not_judged_where_help_would_be_vacuous():
    inf = float("inf")
    # gains that do not act (K = 0: the closed loop is the open loop) do not "help"
    same = pipeline.gains_verdict([0.0, 0.01, 0.1], [50.0, 50.001, 50.004], [50.0, 50.001, 50.004])
    assert same.startswith("no effect"), same
    assert pipeline.gains_verdict([0.01, 0.1], [50.0, 50.003], [50.0, 50.004]) == "help"  # less at one level
    # inf <= inf is no evidence: an open loop that is not finite leaves nothing to judge
    assert pipeline.gains_verdict([0.01, 0.1], [inf, inf], [inf, inf]).startswith("not judged")
    assert pipeline.gains_verdict([0.01], [inf], [1.0]).startswith("do not use")  # the gains blow it up
    for status in ("stationary", "diverged"):
        assert pipeline.gains_verdict([0.01], [1.0], [2.0], status) == f"not judged: the solve is {status}"
    assert pipeline.gains_verdict([0.01], [1.0], [2.0], "converged") == "help"


def test_a_saturated_actuator_identifies_as_exactly_zero_with_the_noise_floor(tmp_path):
    """A position servo held at its force limit moves nothing: its B column is exactly 0.
    Least squares leaves round-off there, which the user-model default noise floor zeroes
    (and nothing else: the other entries are as identified)."""
    from mjx_surrogate.identification import sysid
    from mjx_surrogate.runs.resolution import solver_params

    path = str(tmp_path / "arm.xml")
    open(path, "w").write(ARM.format(actuators=SERVOS.replace('forcerange="-50 50"', 'forcerange="-1 1"')))
    res = resolve(_hold_cfg(path))
    cfg, system, task = res
    assert cfg.sysid.noise_floor == 10.0
    _, sid = solver_params(cfg)
    T = 5
    U = jnp.tile(jnp.asarray([0.4, 2.5]), (T, 1))  # the elbow's target 3.2 rad away: force-limited
    X = jnp.tile(jnp.asarray(task.x0), (T + 1, 1))
    key = jax.random.key(3)
    A, B = jax.jit(sysid.ltv_linearize(system, sid))(X, U, None, key)
    A0, B0 = jax.jit(sysid.ltv_linearize(system, sid.replace(noise_floor=0.0)))(X, U, None, key)
    assert np.all(np.asarray(B[:, :, 1]) == 0.0)
    assert 0 < np.abs(np.asarray(B0[:, :, 1])).max() < 1e-8  # round-off without the floor
    kept = np.abs(np.asarray(B0)) > 1e-6
    np.testing.assert_array_equal(np.asarray(B)[kept], np.asarray(B0)[kept])
    assert np.abs(np.asarray(B[:, :, 0])).max() > 1e-3  # the free shoulder servo is identified


SLIDER = """
<mujoco>
  <option timestep="0.01" gravity="0 0 0"/>
  <worldbody>
    <body name="cart">
      <joint name="rail" type="slide" axis="1 0 0" frictionloss="{friction}"/>
      <geom type="box" size="0.1 0.1 0.1" mass="1"/>
      <body name="pole">
        <joint name="hinge" type="hinge" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0 0 0.5" size="0.02" mass="0.1"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <position joint="rail" kp="5000" ctrlrange="-1 1"/>
    <motor joint="rail" gear="2" ctrlrange="-1 1"/>
    <motor joint="hinge" ctrlrange="-1 1"/>
  </actuator>
</mujoco>
"""


def test_dry_friction_sets_the_perturbation_above_its_break_away(tmp_path):
    """A joint with dry friction f is held (MuJoCo's soft friction lets it creep) until its
    actuator force changes by f: a control change of f / (kp gear) for a servo, f / gear
    for a motor. Checked with mj_step: one step's response per unit control is the same
    at 0.5x and 0.9x that change and more than 4x larger at 2x. A user's model
    with such a joint gets sigma = 10x its smallest break-away, capped at 2e-5; one
    without keeps 1e-6; a given sigma is kept."""
    f = 0.01
    path = tmp_path / "slider.xml"
    path.write_text(SLIDER.format(friction=f))
    m = mujoco.MjModel.from_xml_path(str(path))
    lo, hi = m.actuator_ctrlrange[:, 0], m.actuator_ctrlrange[:, 1]
    x0 = np.zeros(m.nq + m.nv)
    breakaway = model_defaults.breakaway_controls(m, x0, lo, hi)
    np.testing.assert_allclose(breakaway[:2], [f / 5000, f / 2], rtol=1e-9)
    assert breakaway[2] == np.inf  # the hinge has no dry friction
    for a in (0, 1):  # one step's velocity per unit control: the stuck regime below, the free one above

        def response(scale, a=a):
            d = mujoco.MjData(m)
            d.ctrl[a] = scale * breakaway[a]
            mujoco.mj_step(m, d)
            return d.qvel[0] / d.ctrl[a]

        assert response(0.5) == pytest.approx(response(0.9), rel=1e-6)
        assert response(2.0) > 4 * response(0.9) > 0

    def sigmas(friction, **sysid):
        path.write_text(SLIDER.format(friction=friction))
        cfg = Config(
            system=SystemConfig(name="mjcf", mjcf_path=str(path), backend="native"),
            task=TaskConfig(preset="hold"),
            sysid=SysIdConfig(**sysid),
        )
        s = resolve(cfg).config.sysid
        return s.sigma_x, s.sigma_u

    assert sigmas(0.005) == (1e-5, 1e-5)  # 10 f / kp
    assert sigmas(1.0) == (2e-5, 2e-5)  # 10 f / kp = 2e-3, capped
    assert sigmas(0.0) == (1e-6, 1e-6)
    assert sigmas(0.005, sigma_x=3e-6) == (3e-6, 1e-5)


LOOSE = """
<mujoco>
  <worldbody>
    <body name="upper" pos="0 0 1">
      <joint name="shoulder" type="hinge" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.04"/>
      <body name="fore" pos="0.4 0 0">
        <joint name="elbow" type="hinge" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
      </body>
    </body>
    {objects}
  </worldbody>
  <tendon>
    <fixed name="both"><joint joint="shoulder" coef="1"/><joint joint="elbow" coef="0.5"/></fixed>
  </tendon>
  <actuator><motor tendon="both" ctrlrange="-1 1"/></actuator>
</mujoco>
"""
BALL = '<body name="ball" pos="1 0 0.2"><freejoint/><geom type="sphere" size="0.05"/></body>'
DOOR = (
    '<body name="door" pos="-1 0 0.5"><joint type="hinge" axis="0 0 1"/>'
    '<geom type="box" size="0.3 0.02 0.5"/></body>'
)


@pytest.mark.parametrize("objects, loose", [("", []), (BALL, ["ball"]), (BALL + DOOR, ["ball", "door"])])
def test_loose_bodies_are_the_trees_no_actuator_moves_and_get_the_t_test(tmp_path, objects, loose):
    """A tree whose every joint no actuator acts on (a ball, a door) is loose; the arm,
    driven through a tendon only, is not. A user's model with loose objects gets
    sysid.significance 3 where the scheme has the t-test; without them, 0; a given value
    is kept."""
    path = tmp_path / "arm.xml"
    path.write_text(LOOSE.format(objects=objects))
    assert model_defaults.loose_bodies(mujoco.MjModel.from_xml_path(str(path))) == loose

    def significance(**sysid) -> float:
        cfg = Config(
            system=SystemConfig(name="mjcf", mjcf_path=str(path), backend="native"),
            task=TaskConfig(preset="hold"),
            sysid=SysIdConfig(**sysid),
        )
        return resolve(cfg).config.sysid.significance

    assert significance() == (3.0 if loose else 0.0)
    assert significance(significance=0.0) == 0.0
    assert significance(significance=1.5) == 1.5


def test_resolve_warns_where_a_float64_config_meets_float32_jax(tmp_path):
    """A user's MJCF runs in float64 (default_x64); resolved while JAX is in float32 (an API
    user who did not call configure_runtime(x64=True)) the run would silently be float32,
    so resolve warns, naming experiment.x64. In float64, and for a registered float32
    system, it does not."""
    import warnings

    path = tmp_path / "arm.xml"
    path.write_text(LOOSE.format(objects=""))
    system = SystemConfig(name="mjcf", mjcf_path=str(path), backend="native")
    cfg = Config(system=system, task=TaskConfig(preset="hold"))
    with jax.enable_x64(False), pytest.warns(UserWarning, match="experiment.x64"):
        resolve(cfg)
    pendulum = Config(system=SystemConfig(name="pendulum"), task=TaskConfig(preset="pendulum_d2c"))
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        resolve(cfg)
        with jax.enable_x64(False):
            resolve(pendulum)


def test_d2c_mpc_keeps_the_t_test_only_where_its_scheme_has_one(tmp_path):
    """The default t-test of a model with a loose ball reaches D2C-MPC's replans with the
    solver's scheme and with a rollout scheme; the reduced scheme, which has no test,
    gets 0."""
    from mjx_surrogate.runs.config import MPCConfig, MPCSysIdConfig
    from mjx_surrogate.runs.resolution import mpc_params

    path = tmp_path / "arm.xml"
    path.write_text(LOOSE.format(objects=BALL))
    system = SystemConfig(name="mjcf", mjcf_path=str(path), backend="native")

    def significance(**mpc) -> float:
        mpc = MPCConfig(controllers=("d2c",), sysid=MPCSysIdConfig(**mpc))
        cfg = Config(
            system=system, task=TaskConfig(preset="hold"), experiment=ExperimentConfig(kind="mpc"), mpc=mpc
        )
        return mpc_params(resolve(cfg).config)[1].significance

    assert significance() == 3.0
    assert significance(scheme="rollout") == 3.0
    assert significance(scheme="reduced", n_samples=8) == 0.0
