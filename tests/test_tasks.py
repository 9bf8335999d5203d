"""Task costs: the geodesic state error against MuJoCo's own quaternion difference, angle
wrapping, the control reference and point goals against native kinematics."""

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from mjx_surrogate.runs.config import Config, PointGoal, SystemConfig, TaskConfig
from mjx_surrogate.runs.resolution import resolve
from mjx_surrogate.tasks import quat_error, running_cost, state_error, terminal_cost


def _unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


@pytest.mark.parametrize("seed", range(5))
def test_quat_error_matches_mju_subquat(seed):
    rng = np.random.default_rng(seed)
    q, g = _unit(rng.normal(size=4)), _unit(rng.normal(size=4))
    ref = np.zeros(3)
    mujoco.mju_subQuat(ref, q, g)  # rotation vector of g^-1 q
    assert np.allclose(quat_error(jnp.asarray(q), jnp.asarray(g)), ref, atol=1e-10)
    assert np.allclose(quat_error(jnp.asarray(-q), jnp.asarray(g)), ref, atol=1e-10)  # same rotation
    assert np.allclose(quat_error(jnp.asarray(g), jnp.asarray(g)), 0, atol=1e-12)
    grad = jax.grad(lambda a: jnp.sum(quat_error(a, jnp.asarray(g)) ** 2))(jnp.asarray(g))
    assert np.all(np.isfinite(grad))  # smooth at zero error


XML = """<mujoco><worldbody>
  <body name="ball"><freejoint/><geom size=".1" mass="1"/>
    <body pos="0 0 -.5"><joint name="h" type="hinge" axis="0 1 0"/><geom size=".05" mass=".1"/>
      <site name="tip" pos="0 0 -.3"/></body></body>
</worldbody><actuator><motor joint="h" ctrlrange="-2 2"/></actuator>
<keyframe><key name="up" qpos="0 0 1 1 0 0 0 3.0" ctrl="0.5"/></keyframe></mujoco>"""


def test_geodesic_error_wrapping_keyframes_u_ref_and_site_goal(tmp_path):
    path = tmp_path / "m.xml"
    path.write_text(XML)
    goal = PointGoal(name="tip", kind="site", target=(0.1, 0.0, 0.2), weight=2.0, final_weight=3.0)
    cfg = Config(
        system=SystemConfig(name="mjcf", mjcf_path=str(path), backend="native"),
        task=TaskConfig(
            preset="custom",
            T=5,
            goal_keyframe="up",
            Q_diag=(1.0,) * 15,
            Q_f_diag=(1.0,) * 15,
            R_diag=(1.0,),
            goals=(goal,),
        ),
    )
    res = resolve(cfg)
    task, m = res.task, res.system.mj_model
    assert np.allclose(task.u_ref, [0.5]) and np.allclose(task.x_goal[7], 3.0)
    assert np.allclose(task.u_min, [-2]) and np.allclose(task.u_max, [2])  # the model's ctrlrange
    x = np.array(task.x_goal)
    x[7] = 3.0 - 2 * np.pi  # the same angle, one turn away
    x[3:7] = -x[3:7]  # the same orientation
    assert np.allclose(state_error(task, jnp.asarray(x)), 0, atol=1e-12)
    # cost = state terms + control reference + site term, the site from native kinematics
    x = np.array(task.x0)
    x[7] = 0.4
    d = mujoco.MjData(m)
    d.qpos[:] = x[: m.nq]
    mujoco.mj_kinematics(m, d)
    p = d.site_xpos[0]
    e = np.asarray(state_error(task, jnp.asarray(x)))
    u = np.array([1.5])
    expected = 0.5 * e @ e + 0.5 * (u - 0.5) ** 2 + 0.5 * 2.0 * np.sum((p - goal.target) ** 2)
    assert float(running_cost(task, jnp.asarray(x), jnp.asarray(u))) == pytest.approx(float(expected[0]))
    expected_f = 0.5 * e @ e + 0.5 * 3.0 * np.sum((p - goal.target) ** 2)
    assert float(terminal_cost(task, jnp.asarray(x))) == pytest.approx(expected_f)


def test_native_point_kinematics_equal_mjx_with_their_jacobians():
    """Native mj_kinematics through a callback (the native backend's point goals) against
    MJX kinematics: positions and Jacobians (custom JVP by central differences against
    jax.jacfwd through MJX), batched, inside jit, on a free-floating body."""
    from mjx_surrogate.systems.kinematics import make_points_fn, native_points_fn

    m = mujoco.MjModel.from_xml_string(XML)
    ids = [("site", 0), ("body", 2)]
    native, mjx_fn = native_points_fn(m, ids), make_points_fn(m, ids)
    rng = np.random.default_rng(0)
    X = np.concatenate([rng.normal(size=(6, m.nq)), rng.normal(size=(6, m.nv))], axis=1)
    X[:, 3:7] /= np.linalg.norm(X[:, 3:7], axis=1, keepdims=True)
    X = jnp.asarray(X)
    np.testing.assert_allclose(jax.jit(jax.vmap(native))(X), jax.jit(jax.vmap(mjx_fn))(X), atol=1e-12)
    Jn = jax.jit(jax.vmap(jax.jacfwd(native)))(X)
    Jm = jax.jit(jax.vmap(jax.jacfwd(mjx_fn)))(X)
    assert Jn.shape == (6, 2, 3, m.nq + m.nv)
    np.testing.assert_allclose(Jn, Jm, atol=1e-8)


def test_several_quaternion_blocks_each_get_their_rotation_vector_from_one_program():
    """A free joint and two ball joints (three quaternion blocks) around a hinge: each block's
    error is MuJoCo's own quaternion difference and the hinge is wrapped; the blocks share
    one vmapped error, so the program holds one arctan2 however many blocks there are."""
    from mjx_surrogate.tasks import make_task

    quats, hinge, nq, nv = (3, 7, 12), 11, 16, 13
    rng = np.random.default_rng(7)
    x, goal = rng.normal(size=nq + nv), rng.normal(size=nq + nv)
    for a in quats:
        x[a : a + 4], goal[a : a + 4] = _unit(x[a : a + 4]), _unit(goal[a : a + 4])
    x[hinge] = goal[hinge] + 0.3 + 4 * np.pi
    eye = np.eye(nq + nv)
    task = make_task(x, goal, eye, eye, np.eye(1), 5, quats=quats, hinges=(hinge,))
    e = np.asarray(state_error(task, jnp.asarray(x)))
    for a in quats:
        ref = np.zeros(3)
        mujoco.mju_subQuat(ref, x[a : a + 4], goal[a : a + 4])
        assert e[a] == 0.0 and np.allclose(e[a + 1 : a + 4], ref, atol=1e-10), a
    assert e[hinge] == pytest.approx(0.3)
    rest = np.setdiff1d(np.arange(nq + nv), [i for a in quats for i in range(a, a + 4)] + [hinge])
    np.testing.assert_array_equal(e[rest], (x - goal)[rest])
    program = jax.jit(lambda x: running_cost(task, x, jnp.zeros(1))).lower(jnp.asarray(x)).as_text()
    assert program.count("atan2") == 1
