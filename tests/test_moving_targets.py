"""Moving point-goal targets on a model we did not write (gymnasium's reacher, downloaded at
test time): resolved from the config, judged where the target is at the end, and followed
in closed loop by planners that see it where it will be."""

import dataclasses

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from mjx_surrogate.runs import pipeline
from mjx_surrogate.runs.config import Config, PointGoal, SystemConfig, TaskConfig
from mjx_surrogate.runs.resolution import resolve
from mjx_surrogate.tasks import point_distances, targets_at
from tests.thirdparty import model_path

DT = 0.02


def _reacher(goal: PointGoal, T: int = 25):
    path = model_path("gymnasium", "reacher.xml")
    if path is None:
        pytest.skip("gymnasium's wheel cannot be downloaded")
    cfg = Config(
        system=SystemConfig(name="mjcf", mjcf_path=path, backend="native", control_dt=DT),
        task=TaskConfig(preset="custom", T=T, goals=(goal,)),
    )
    return cfg, resolve(cfg)


def _fingertip(m: mujoco.MjModel, x) -> np.ndarray:
    d = mujoco.MjData(m)
    d.qpos[:] = np.asarray(x)[: m.nq]
    mujoco.mj_kinematics(m, d)
    return d.xpos[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "fingertip")].copy()


def test_a_moving_target_resolves_once_and_the_goal_test_judges_it_where_it_ends():
    """The target moves from p_a (the fingertip at state xa) to p_1 (at state x1) in N steps
    at a constant velocity: a trajectory ending at x1 reaches it, one that holds p_a does not
    (with the target fixed at p_a, it would); the per-step test passes at the end only; an
    orbit adds its circle through the start."""
    goal = PointGoal(name="fingertip", kind="body", target=(0.0, 0.0, 0.0), final_weight=100.0)
    cfg, res = _reacher(goal)
    m, N = res.system.mj_model, 20
    x0, xa, x1 = (np.zeros(m.nq + m.nv) for _ in range(3))
    xa[:2], x1[:2] = (0.3, 0.5), (1.2, -0.4)
    p_a, p_1 = _fingertip(m, xa), _fingertip(m, x1)
    v = (p_1 - p_a) / (N * DT)
    moving = dataclasses.replace(goal, target=tuple(p_a), velocity=tuple(v))
    fixed_cfg = dataclasses.replace(
        cfg, task=dataclasses.replace(cfg.task, goals=(dataclasses.replace(moving, velocity=(0, 0, 0)),))
    )
    moving_cfg = dataclasses.replace(cfg, task=dataclasses.replace(cfg.task, goals=(moving,)))
    task, fixed = resolve(moving_cfg).task, resolve(fixed_cfg).task
    assert fixed.motion is None and task.motion is not None
    np.testing.assert_allclose(targets_at(task, N)[0], p_1, atol=1e-12)
    ramp = np.linspace(0, 1, N + 1)[:, None]

    def path(x_end):  # N + 1 states from x0 to x_end
        return jnp.asarray((1 - ramp) * x0 + ramp * x_end)

    tol = cfg.task.goal_tolerance
    assert pipeline.goal_test(task, path(x1), tol)["reached"]
    assert not pipeline.goal_test(task, path(xa), tol)["reached"]
    assert pipeline.goal_test(fixed, path(xa), tol)["reached"]
    passes = pipeline.goal_passes(task, path(x1), tol)
    assert passes[-1] and not passes[0]
    # the loops' tracking metric: each state's point against the target of its own step
    d = np.asarray(point_distances(task, path(x1)))
    assert d.shape == (N + 1,) and d[-1] == pytest.approx(0.0, abs=1e-12)
    assert d[0] == pytest.approx(np.linalg.norm(_fingertip(m, x0) - p_a), abs=1e-12)
    mid = (1 - ramp[N // 2, 0]) * x0 + ramp[N // 2, 0] * x1
    expected = np.linalg.norm(_fingertip(m, mid) - (p_a + v * (N // 2) * DT))
    assert d[N // 2] == pytest.approx(expected, abs=1e-12)
    # an orbit: a circle through the start, a quarter turn after a quarter period
    orbit = dataclasses.replace(
        goal, target=tuple(p_a), orbit_radius=0.05, orbit_period=N * DT, orbit_plane="xy"
    )
    circling = resolve(dataclasses.replace(cfg, task=dataclasses.replace(cfg.task, goals=(orbit,)))).task
    quarter = np.asarray(targets_at(circling, N // 4)[0]) - p_a
    np.testing.assert_allclose(quarter, [-0.05, 0.05, 0.0], atol=1e-12)


@pytest.mark.slow  # over 5 s: the fast tier's budget
def test_d2c_mpc_follows_a_moving_target_where_it_will_be():
    """D2C-MPC (H = 10, receding) steers the reacher's fingertip to a target that starts
    0.11 m away and moves 0.1 m in the 25 steps of the episode: the closed loop ends at the
    moved target (the goal test), which a planner that saw the target where it was at the
    episode's start would miss."""
    from mjx_surrogate.control.ilqr import ILQRParams
    from mjx_surrogate.control.mpc import receding_horizon

    goal = PointGoal(name="fingertip", kind="body", target=(0.0, 0.0, 0.0), weight=10.0, final_weight=1000.0)
    cfg, res = _reacher(goal)
    m = res.system.mj_model
    start = _fingertip(m, res.task.x0) + np.array([-0.05, 0.1, 0.0])
    moving = dataclasses.replace(goal, target=tuple(start), velocity=(-0.2, 0.0, 0.0))
    _, system, task = resolve(dataclasses.replace(cfg, task=dataclasses.replace(cfg.task, goals=(moving,))))
    H = 10
    r = receding_horizon(
        system,
        task.replace(T=H),
        jnp.zeros((H, system.nu)),
        key=jax.random.key(0),
        steps=task.T,
        params=ILQRParams(max_iter=2),
    )
    test = pipeline.goal_test(task, r.X, cfg.task.goal_tolerance)
    assert test["reached"], test
    end = np.asarray(targets_at(task, task.T)[0])
    assert np.linalg.norm(_fingertip(m, r.X[-1]) - end) < 0.01
    assert np.linalg.norm(end - start) == pytest.approx(0.1)
