"""Task costs: the geodesic state error against MuJoCo's own quaternion difference, angle
wrapping, the control reference and point goals against native kinematics."""

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from mjx_surrogate.runs.config import Config, PointGoal, SystemConfig, TaskConfig
from mjx_surrogate.runs.resolution import resolve
from mjx_surrogate.tasks import make_task, quat_error, running_cost, state_error, terminal_cost


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


HINGES = """<mujoco><worldbody><body><joint type="slide" axis="1 0 0"/><geom size=".1" mass="1"/>
<body pos="0 0 .3"><joint type="hinge" axis="0 1 0"/><geom size=".1" mass="1"/>
<body pos=".2 0 .3"><joint type="hinge" axis="1 1 0"/><geom size=".1" mass="1"/>
<site name="tip" pos=".1 .05 .2"/></body></body></body></worldbody></mujoco>"""


def test_native_point_jacobians_of_hinges_and_slides_are_mujocos_own():
    """Where every joint is a hinge or a slide the native points' Jacobian is MuJoCo's
    mj_jacSite / mj_jacBody: jacfwd through MJX's kinematics to 1e-12 (central differences
    agree only to about 1e-9), zero beyond qpos."""
    from mjx_surrogate.systems.kinematics import make_points_fn, native_points_fn

    m = mujoco.MjModel.from_xml_string(HINGES)
    ids = [("site", 0), ("body", 3)]
    native, mjx_fn = native_points_fn(m, ids), make_points_fn(m, ids)
    X = jnp.asarray(np.random.default_rng(1).normal(size=(5, 2 * m.nq)))
    Jn = jax.jit(jax.vmap(jax.jacfwd(native)))(X)
    Jm = jax.jit(jax.vmap(jax.jacfwd(mjx_fn)))(X)
    assert Jn.shape == (5, 2, 3, 6) and np.all(np.asarray(Jn)[..., m.nq :] == 0)
    np.testing.assert_allclose(Jn, Jm, atol=1e-12)


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


def _ending_task(points: bool):
    """nx 4, nu 2, T 6, random weights; with ``points``, two goal points linear in x (so
    that Gauss-Newton's Hessian is the exact one)."""
    rng = np.random.default_rng(3)
    sym = lambda n: (lambda M: M @ M.T)(rng.normal(size=(n, n)))  # noqa: E731
    kw = {}
    if points:
        P = jnp.asarray(rng.normal(size=(2, 3, 4)))
        kw = dict(targets=rng.normal(size=(2, 3)), weights=[0.5, 2.0], final_weights=[3.0, 1.0])
        kw["points"] = lambda x: P @ x
    task = make_task(
        rng.normal(size=4), rng.normal(size=4), sym(4), sym(4), sym(2), 6, u_ref=rng.normal(size=2), **kw
    )
    return task.replace(deadline=9), rng.normal(size=(7, 4)), rng.normal(size=(6, 2))


def _ending_reference(task, end, X, U):
    """J_E of the tasks module docstring, stage by stage in plain jnp."""
    J = 0.0
    for t in range(task.T):
        du = U[t] - task.u_ref
        J += 0.5 * du @ task.R @ du
        if t < end:
            J += running_cost(task, X[t], U[t]) - 0.5 * du @ task.R @ du
        if t == end:
            J += terminal_cost(task, X[t])
    return J + (terminal_cost(task, X[-1]) if end == task.T else 0.0)


def _assert_stagewise(derivatives, grads, hessians, T: int, atol: float) -> None:
    """The solver's cost derivatives (l_x, l_u, l_xx, l_uu, l_ux, V_x, V_xx) against the
    gradient (X [T+1], U [T]) and the Hessian blocks (XX, XU, UU) of a whole-trajectory
    reference, stage by stage."""
    lx, lu, lxx, luu, lux, Vx, Vxx = derivatives
    (gX, gU), (hXX, hXU, hUU) = grads, hessians
    np.testing.assert_allclose(lx, gX[:T], atol=atol)
    np.testing.assert_allclose(Vx, gX[T], atol=atol)
    np.testing.assert_allclose(lu, gU, atol=atol)
    np.testing.assert_allclose(lxx, [hXX[t, :, t] for t in range(T)], atol=atol)
    np.testing.assert_allclose(Vxx, hXX[T, :, T], atol=atol)
    np.testing.assert_allclose(luu, [hUU[t, :, t] for t in range(T)], atol=atol)
    np.testing.assert_allclose(lux, [hXU[t, :, t].T for t in range(T)], atol=atol)


@pytest.mark.slow  # over 5 s: the fast tier's budget
@pytest.mark.parametrize("points", [False, True], ids=["quadratic", "point goals"])
def test_a_task_that_ends_within_its_horizon_costs_and_differentiates_as_written(points):
    """at_step at control step n of an episode with deadline 9 ends a horizon-6 task at
    stage clip(9 - n, 0, 6): the cost is J_E (running before the end, terminal at it, effort
    after it) and its derivatives are those of J_E, stage by stage (autodiff of a loop
    written apart; the point goals' Gauss-Newton Hessian is exact for linear points)."""
    from mjx_surrogate.control.riccati import cost_derivatives
    from mjx_surrogate.tasks import at_step, task_cost, trajectory_cost

    task, X, U = _ending_task(points)
    X, U = jnp.asarray(X), jnp.asarray(U)
    plain = task.replace(deadline=None)
    assert at_step(plain, 4) is plain and task_cost(task).timed is False
    # one program for the stages' end as an argument; the reference's per end (a Python loop)
    derivatives = jax.jit(lambda e, X, U: (trajectory_cost(e, X, U), cost_derivatives(task_cost(e), X, U)))
    reference = jax.jit(
        lambda task, end, X, U: (
            _ending_reference(task, end, X, U),
            jax.grad(_ending_reference, (2, 3))(task, end, X, U),
            jax.hessian(_ending_reference, (2, 3))(task, end, X, U),
        ),
        static_argnums=1,
    )
    for n, end in [(3, 6), (5, 4), (8, 1), (9, 0), (12, 0)]:
        ended = at_step(task, jnp.asarray(n))
        assert int(ended.end) == end and task_cost(ended).timed
        J, (lx, lu, lxx, luu, lux, Vx, Vxx) = derivatives(ended, X, U)
        J_ref, (gX, gU), ((hXX, hXU), (_, hUU)) = reference(task, end, X, U)
        assert float(J) == pytest.approx(float(J_ref), rel=1e-12)
        _assert_stagewise((lx, lu, lxx, luu, lux, Vx, Vxx), (gX, gU), (hXX, hXU, hUU), task.T, 1e-10)
    full = at_step(task.replace(deadline=6), 0)  # ends at the horizon's end: the usual J
    assert float(trajectory_cost(full, X, U)) == pytest.approx(float(trajectory_cost(task, X, U)), rel=1e-12)


def _circling_targets(p0, v, r, period, axes, s):
    """Targets [k, 3] after s seconds, written from the circle's centre (p0 - r e1): the
    centre moved by v s, plus r (cos phi, sin phi) in the plane's axes."""
    out = []
    for k in range(len(p0)):
        e1, e2 = np.eye(3)[axes[k][0]], np.eye(3)[axes[k][1]]
        phi = 2 * np.pi * s / period[k]
        centre = np.asarray(p0[k]) - r[k] * e1 + np.asarray(v[k]) * s
        out.append(centre + r[k] * (np.cos(phi) * e1 + np.sin(phi) * e2))
    return np.array(out)


@pytest.mark.slow  # over 5 s: the fast tier's budget
@pytest.mark.parametrize("gauss_newton", [True, False], ids=["gauss-newton", "exact"])
def test_moving_targets_cost_and_differentiate_where_the_targets_are_at_each_stage(gauss_newton):
    """Two point goals linear in x, one circling in the xz plane, one moving at a constant
    velocity while circling in yz: planned at control step n, stage t's running cost and the
    terminal cost use the targets after n + t and n + T steps (a reference written from the
    circles' centres, stage by stage), and so do the cost's derivatives (autodiff of the
    reference); an episode's cost puts its terminal at its own length."""
    from mjx_surrogate.control.riccati import cost_derivatives
    from mjx_surrogate.moving_targets import target_motion
    from mjx_surrogate.tasks import at_step, task_cost, trajectory_cost

    rng = np.random.default_rng(5)
    dt, T = 0.05, 6
    v, r, period, planes = [(0.0, 0.0, 0.0), (0.3, -0.2, 0.1)], [0.2, 0.1], [1.0, 0.7], ["xz", "yz"]
    axes = [(0, 2), (1, 2)]
    P = rng.normal(size=(2, 3, 4))
    p0 = rng.normal(size=(2, 3))
    sym = lambda n: (lambda M: M @ M.T)(rng.normal(size=(n, n)))  # noqa: E731
    motion = target_motion(v, r, period, planes, dt)
    task = make_task(
        rng.normal(size=4), rng.normal(size=4), sym(4), sym(4), sym(2), T, u_ref=rng.normal(size=2),
        targets=p0, weights=[0.5, 2.0], final_weights=[3.0, 1.0], points=lambda x: jnp.asarray(P) @ x,
        motion=motion, gauss_newton=gauss_newton,
    )  # fmt: skip
    X, U = jnp.asarray(rng.normal(size=(T + 1, 4))), jnp.asarray(rng.normal(size=(T, 2)))

    def reference(X, U, n):
        J = 0.0
        for t in range(T + 1):
            d = jnp.einsum("kcn,n->kc", P, X[t]) - _circling_targets(p0, v, r, period, axes, (n + t) * dt)
            if t < T:
                e, du = X[t] - task.x_goal, U[t] - task.u_ref
                J += (
                    0.5 * e @ task.Q @ e
                    + 0.5 * du @ task.R @ du
                    + 0.5 * jnp.sum(task.weights * jnp.sum(d**2, -1))
                )
            else:
                e = X[t] - task.x_goal
                J += 0.5 * e @ task.Q_f @ e + 0.5 * jnp.sum(task.final_weights * jnp.sum(d**2, -1))
        return J

    assert task_cost(task).timed
    program = jax.jit(
        lambda task, X, U: (trajectory_cost(task, X, U), cost_derivatives(task_cost(task), X, U))
    )
    for n in (0, 3, 11):
        planned = at_step(task, jnp.asarray(n))
        J, (lx, lu, lxx, luu, lux, Vx, Vxx) = program(planned, X, U)
        assert float(J) == pytest.approx(float(reference(X, U, n)), rel=1e-12)
        gX, gU = jax.grad(reference, (0, 1))(X, U, n)
        (hXX, hXU), (_, hUU) = jax.hessian(reference, (0, 1))(X, U, n)
        _assert_stagewise((lx, lu, lxx, luu, lux, Vx, Vxx), (gX, gU), (hXX, hXU, hUU), T, 1e-9)
    # an episode of 9 steps from step 0: its terminal is against the targets after 9 steps
    Xe, Ue = jnp.asarray(rng.normal(size=(10, 4))), jnp.asarray(rng.normal(size=(9, 2)))
    Te = 9
    d = jnp.einsum("kcn,n->kc", P, Xe[Te]) - _circling_targets(p0, v, r, period, axes, Te * dt)
    e = Xe[Te] - task.x_goal
    terminal = 0.5 * e @ task.Q_f @ e + 0.5 * jnp.sum(task.final_weights * jnp.sum(d**2, -1))
    running = sum(float(running_cost(task, Xe[t], Ue[t], t)) for t in range(Te))
    assert float(trajectory_cost(task, Xe, Ue)) == pytest.approx(running + float(terminal), rel=1e-12)
