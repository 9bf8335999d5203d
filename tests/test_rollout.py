"""Batched rollouts: shapes, backends agree, determinism per key, no recompilation."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mjx_surrogate.identification.rollout import perturbed_rollouts, rollout


@pytest.mark.slow
def test_rollout_backends_agree_and_shapes(systems):
    """A batch of rollouts on both backends (the pendulum: a fifth of the cartpole's MJX
    compile; each backend against mj_step on constrained models: tests/test_systems.py)."""
    mjx_sys, nat_sys = systems("pendulum", "mjx"), systems("pendulum", "native")
    key = jax.random.key(0)
    x0 = 0.1 * jax.random.normal(key, (64, 2))
    U = jax.random.normal(jax.random.key(1), (64, 15, 1))
    Xm = rollout(mjx_sys, x0, U)
    Xn = rollout(nat_sys, x0, U)
    assert Xm.shape == Xn.shape == (64, 16, 2)
    assert Xm.dtype == Xn.dtype == jnp.float64
    np.testing.assert_allclose(Xm, Xn, atol=1e-9)
    np.testing.assert_array_equal(Xm[:, 0], x0)


@pytest.mark.slow
def test_perturbed_rollouts_deterministic_and_distributed(systems):
    s = systems("pendulum", "mjx")
    x0 = jnp.array([np.pi - 0.1, 0.0])
    U = jnp.zeros((10, 1))
    a = perturbed_rollouts(s, jax.random.key(7), x0, U, 4096, 0.01, 0.2)
    b = perturbed_rollouts(s, jax.random.key(7), x0, U, 4096, 0.01, 0.2)
    c = perturbed_rollouts(s, jax.random.key(8), x0, U, 4096, 0.01, 0.2)
    np.testing.assert_array_equal(a.X, b.X)
    assert not np.allclose(a.X, c.X)
    assert a.X.shape == (4096, 11, 2) and a.dU.shape == (4096, 10, 1)
    # Sample std of the draws within 4 standard errors of the requested scale.
    assert abs(float(jnp.std(a.dU)) - 0.2) < 4 * 0.2 / np.sqrt(2 * a.dU.size)
    assert abs(float(jnp.std(a.dx0)) - 0.01) < 4 * 0.01 / np.sqrt(2 * a.dx0.size)
    # Each perturbed trajectory is exactly the rollout of its perturbed inputs.
    X = rollout(s, x0[None] + a.dx0[:5], U[None] + a.dU[:5])
    np.testing.assert_allclose(X, a.X[:5], atol=1e-12)


def test_no_recompilation_for_new_values(systems):
    s = systems("pendulum", "mjx")
    U = jnp.zeros((10, 1))
    perturbed_rollouts(s, jax.random.key(0), jnp.zeros(2), U, 8, 0.1, 0.1)
    n = perturbed_rollouts._cache_size()
    perturbed_rollouts(s, jax.random.key(1), jnp.ones(2), U + 1, 8, 0.3, 0.2)
    assert perturbed_rollouts._cache_size() == n


def test_a_trial_mujoco_raises_on_is_marked_diverged(systems):
    """The native line search marks a step size whose simulation MuJoCo raised an error on
    (``mujoco.batch.SimulationError``) as diverged from that control step on; the other
    step sizes run on unchanged."""
    from mujoco import batch as mj_batch

    sim = systems("cartpole", backend="native").native
    T, A = 8, 3
    x0, Ub = np.array([0.0, 3.0, 0.0, 0.0]), np.full((T, 1), 0.2)
    Xb, k, K = sim(x0, Ub), np.ones((T, 1)), np.zeros((T, 1, 4))
    alphas, lo, hi = np.array([1.0, 0.5, 0.25]), np.array([-np.inf]), np.array([np.inf])
    X0, _ = sim.closed_loop(x0, Xb, Ub, k, K, alphas, lo, hi)
    batch = sim._take_batch(A)
    calls = []

    def step_raising_at_the_fourth_call(**kw):
        mj_batch.Batch.step(batch, **kw)
        calls.append(1)
        if len(calls) == 4:
            batch.state[1] = -1.0  # MuJoCo keeps the pre-call state; the value is unused
            raise mj_batch.SimulationError(np.array([1]), "test")

    batch.step = step_raising_at_the_fourth_call
    sim._batches[A].put(batch)
    X1, _ = sim.closed_loop(x0, Xb, Ub, k, K, alphas, lo, hi)
    assert len(calls) == T
    assert np.isnan(X1[1, 4:]).all() and np.array_equal(X1[1, :4], X0[1, :4])
    np.testing.assert_array_equal(X1[[0, 2]], X0[[0, 2]])


def test_native_one_step_equals_the_rollout_of_one_step(systems):
    """NativeSimulator.step (the identification's one-step batches: buffers reused, MuJoCo's
    checks skipped) = the horizon-1 rollout bit for bit, rows with a non-finite or huge
    control and a state beyond mjMAXVAL marked NaN, in float64 and float32, over repeated
    calls and batch sizes; the jitted native step calls it once per vmapped batch."""
    import mujoco

    s = systems("fish", backend="native", native_threads=2)
    sim = s.native
    rng = np.random.default_rng(1)
    x_rest = np.concatenate([s.mj_model.qpos0, np.zeros(sim.nx - s.nq)])
    for B, dtype in ((70, np.float64), (3, np.float64), (70, np.float32), (70, np.float64)):
        x = (x_rest + 1e-2 * rng.standard_normal((B, sim.nx))).astype(dtype)
        u = rng.standard_normal((B, s.nu)).astype(dtype)
        u[1, 0], u[2, 3] = np.nan, 2 * mujoco.mjMAXVAL
        x[-1, 0] = 2 * mujoco.mjMAXVAL
        ref = sim(x, u[:, None, :])[:, 1]
        out = sim.step(x, u)
        sim.step(x[::-1].copy(), u)  # the same buffers again: out must not change
        assert out.dtype == dtype and out.shape == (B, sim.nx)
        np.testing.assert_array_equal(out, ref)
        assert np.isnan(out[[1, 2, -1]]).all() and np.isfinite(out[3:-1]).all()
    calls = []
    orig = sim.step
    sim.step = lambda x, u: calls.append(np.shape(x)) or orig(x, u)
    try:
        xs, us = jnp.asarray(x[3:-1]), jnp.asarray(u[3:-1])
        out = jax.jit(jax.vmap(s.step))(xs, us)
    finally:
        del sim.step
    assert calls == [(B - 4, sim.nx)]
    np.testing.assert_array_equal(np.asarray(out), ref[3:-1])


_SENSED = """
<mujoco>
  <worldbody>
    <body><joint name="hinge" type="hinge" axis="0 1 0" damping="0.1"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.5" size="0.05"/></body>
  </worldbody>
  <actuator><motor joint="hinge" ctrlrange="-2 2"/></actuator>
  <sensor><jointpos joint="hinge"/><jointvel joint="hinge"/></sensor>
</mujoco>
"""


_PID_PLUGIN = """<extension><plugin plugin="mujoco.pid">
  <instance name="pid"><config key="kp" value="4"/></instance></plugin></extension>"""


def _mj_steps(m, x, u, substeps):
    import mujoco

    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:], d.ctrl[:] = x[: m.nq], x[m.nq :], u
    for _ in range(substeps):
        mujoco.mj_step(m, d)
    return np.concatenate([d.qpos, d.qvel])


def test_native_sensors_are_off_unless_they_can_act():
    """The native simulator switches off the sensors the solver never reads; with a MuJoCo
    control callback installed (it runs after the sensors and may read them) they stay on.
    Either way its states are mj_step's with the sensors on, bit for bit."""
    import mujoco

    from mjx_surrogate.systems.backend_native import NativeSimulator

    m = mujoco.MjModel.from_xml_string(_SENSED)
    x, u = np.array([0.3, -0.2]), np.array([0.5])
    off = NativeSimulator(m, substeps=3, nthread=1)
    assert off.model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_SENSOR
    assert not m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_SENSOR  # the user's model untouched
    np.testing.assert_array_equal(off.step(x[None], u[None])[0], _mj_steps(m, x, u, 3))
    np.testing.assert_array_equal(off(x, u[None])[1], _mj_steps(m, x, u, 3))

    def feedback(model, data):  # a user's controller that reads the sensors
        data.ctrl[0] = -2.0 * data.sensordata[0] - 0.5 * data.sensordata[1]

    mujoco.set_mjcb_control(feedback)
    try:
        on = NativeSimulator(m, substeps=3, nthread=1)
        want = _mj_steps(m, x, u, 3)
        assert not on.model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_SENSOR
        np.testing.assert_array_equal(on.step(x[None], u[None])[0], want)
        assert not np.array_equal(want, off.step(x[None], u[None])[0])  # the sensors act here
    finally:
        mujoco.set_mjcb_control(None)
    motor = '<motor joint="hinge" ctrlrange="-2 2"/>'
    servo = '<plugin joint="hinge" plugin="mujoco.pid" instance="pid"/>'
    pid = _SENSED.replace("<worldbody>", _PID_PLUGIN + "<worldbody>").replace(motor, servo)
    kept = NativeSimulator(mujoco.MjModel.from_xml_string(pid), substeps=3, nthread=1)
    assert not kept.model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_SENSOR  # a plugin may act
