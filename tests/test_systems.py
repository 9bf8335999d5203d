"""Systems: MJX step against native mujoco.mj_step, dimensions, constraint flags, MJCF."""

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from mjx_surrogate.errors import ConfigError
from mjx_surrogate.systems import from_mjcf, make_system
from mjx_surrogate.systems.system import state_labels

DIMS = {
    "pendulum": (2, 1),
    "cartpole": (4, 1),
    "fish": (27, 5),
    "swimmer3": (10, 2),
    "swimmer6": (16, 5),
    "swimmer15": (34, 14),
}


def native_reference(system, x0, U):
    """Independent reference: plain mujoco.mj_step on a fresh MjData, float64."""
    m = system.mj_model
    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:] = x0[: m.nq], x0[m.nq :]
    out = [x0.copy()]
    for u in U:
        d.ctrl[:] = u
        for _ in range(system.substeps):
            mujoco.mj_step(m, d)
        out.append(np.concatenate([d.qpos, d.qvel]))
    return np.stack(out)


def initial_state(system, rng, scale=0.1):
    x0 = np.concatenate([system.mj_model.qpos0, np.zeros(system.nv)])
    x0 = x0 + scale * rng.standard_normal(system.nx)
    if system.name == "fish":  # keep the quaternion a unit quaternion
        x0[3:7] = x0[3:7] / np.linalg.norm(x0[3:7])
    return x0


# name, horizon, tolerance (float64; chaotic growth bounds the horizon)
CASES = [
    ("pendulum", 50, 1e-9),
    ("cartpole", 50, 1e-9),
    ("fish", 30, 1e-8),
    ("swimmer6", 20, 1e-8),  # the swimmer3's model comes from the same template
]


@pytest.mark.slow
@pytest.mark.parametrize("name,T,tol", CASES)
def test_mjx_step_matches_mj_step(systems, name, T, tol):
    s = systems(name, "mjx")
    rng = np.random.default_rng(0)
    x0 = initial_state(s, rng)
    U = 0.5 * rng.standard_normal((T, s.nu))
    ref = native_reference(s, x0, U)
    X = np.asarray(jax.jit(s.rollout)(jnp.asarray(x0)[None], jnp.asarray(U)[None])[0])
    assert X.dtype == np.float64
    np.testing.assert_allclose(X, ref, atol=tol, rtol=0)


@pytest.mark.parametrize("name", ["pendulum", "cartpole", "fish", "swimmer6"])
def test_native_backend_matches_mj_step(systems, name):
    s = systems(name, "native")
    rng = np.random.default_rng(1)
    x0 = initial_state(s, rng)
    U = 0.5 * rng.standard_normal((20, s.nu))
    ref = native_reference(s, x0, U)
    X = np.asarray(jax.jit(s.rollout)(jnp.asarray(x0)[None], jnp.asarray(U)[None])[0])
    np.testing.assert_allclose(X, ref, atol=1e-12, rtol=0)


@pytest.mark.parametrize("name", list(DIMS))
def test_dimensions_and_labels(name):
    s = make_system(name, backend="native")
    assert (s.nx, s.nu) == DIMS[name]
    assert len(state_labels(s.mj_model)) == s.nx
    assert s.dt == pytest.approx(s.mj_model.opt.timestep * s.substeps)


def test_constraint_solver_disabled_only_without_constraints():
    flag = mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    for name in ("pendulum", "cartpole", "fish"):
        assert make_system(name, backend="native").mj_model.opt.disableflags & flag
    # swimmer joints are limited: the solver must stay on
    assert not make_system("swimmer6", backend="native").mj_model.opt.disableflags & flag
    # and the exact MJCF saved reflects what was simulated
    assert 'constraint="disable"' in make_system("pendulum", backend="native").xml


def test_native_backend_marks_divergence_as_nan(systems):
    s = systems("cartpole", "native")
    x0 = np.zeros((4, 4))
    U = np.zeros((4, 5, 1))
    U[0, 2, 0] = np.nan  # MuJoCo would silently zero this control
    U[1, 1, 0] = 1e30  # and this one
    x0[2, 2] = 1e30  # and reset this state, at the first step, from time 0
    X = s.native(x0, U)
    assert np.isfinite(X[0, :3]).all() and np.isfinite(X[1, :2]).all() and np.isfinite(X[3]).all()
    assert np.isnan(X[0, 3:]).all() and np.isnan(X[1, 2:]).all() and np.isnan(X[2, 1:]).all()
    # a one-step call with one physics step too: there a reset left no trace in the time
    one = systems("cartpole", "native", substeps=1).native(x0[2:], U[2:, :1])[:, 1]
    assert np.isnan(one[0]).all() and np.isfinite(one[1]).all()


def test_from_mjcf_user_model(tmp_path, systems):
    xml = systems("pendulum", "native").xml
    path = tmp_path / "my_pendulum.xml"
    path.write_text(xml)
    s = from_mjcf(str(path), backend="native", substeps=5)
    ref = systems("pendulum", "native")
    x0 = np.array([[0.3, 0.0]])
    U = np.full((1, 10, 1), 0.2)
    np.testing.assert_allclose(s.native(x0, U), ref.native(x0, U), atol=1e-12)
    assert s.name == "my_pendulum"


@pytest.mark.parametrize(
    "text,needle",
    [
        ("<mujoco><worldbody><body></mujoco>", "invalid MJCF"),
        (
            "<mujoco><worldbody><body><joint type='hinge'/><geom size='.1'/></body></worldbody></mujoco>",
            "no actuators",
        ),
    ],
)
def test_broken_mjcf_is_a_config_error(tmp_path, text, needle):
    path = tmp_path / "broken.xml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=needle) as err:
        from_mjcf(str(path))
    assert str(err.value).startswith("system.mjcf_path:")
    assert "\n" not in str(err.value)


def test_unknown_system_names_the_field():
    with pytest.raises(ConfigError, match=r"^system.name: unknown system 'swimmer1'"):
        make_system("swimmer1")


def test_mjx_step_first_built_inside_a_trace_does_not_leak():
    """A native system's lazily built MJX step, first touched inside jit, stays usable."""
    import jax
    import jax.numpy as jnp

    from mjx_surrogate.systems import make_system

    sys_ = make_system("pendulum", backend="native")
    x, u = jnp.array([0.3, 0.0]), jnp.array([0.1])
    inside = jax.jit(lambda a, b: sys_.mjx_step(a, b))(x, u)
    outside = jax.jit(lambda a, b: sys_.mjx_step(a, b) * 1.0)(x, u)
    assert jnp.allclose(inside, outside)


def test_building_the_mjx_step_compiles_no_physics_eagerly():
    """The MJX step's build (float64: the carry's dtypes from an abstract step) runs no
    physics op by op: done under compile-time evaluation, it compiled every inner jit of
    ``mjx.step`` as it went (pendulum 177 programs, the fish 15 s)."""
    import collections

    import jax
    import mujoco

    from mjx_surrogate.systems import backend_mjx
    from mjx_surrogate.systems.registry import default_config

    assert jax.config.jax_enable_x64  # conftest: the case with the dtype pass
    events = collections.Counter()

    def count(name, _, **kw):
        events.update([name])

    jax.monitoring.register_event_duration_secs_listener(count)
    try:
        backend_mjx.make_mjx_step(mujoco.MjModel.from_xml_string(default_config("pendulum").xml()), 2)
    finally:
        jax.monitoring.unregister_event_duration_listener(count)
    assert events["/jax/core/compile/jaxpr_to_mlir_module_duration"] <= 20, events


@pytest.mark.slow
@pytest.mark.parametrize("name", ["cartpole", "fish"])
def test_mjx_programs_hold_no_lapack_call(systems, name):
    """Batched LAPACK deadlocked jaxlib 0.10 on 2 cores (docs/performance.md): the MJX
    step, vmapped and differentiated as the oracle uses it, must compile without it. The
    oracle's Jacobian program pushes tangents through the batched physics step and computes
    that step too, so its text holds every operation the batched step's does (lowering the
    step's own program as well took 2-3 s more per model)."""
    import re

    import jax
    import jax.numpy as jnp

    sys_ = systems(name)
    x = jnp.zeros((3, sys_.nx)).at[:, : sys_.nq].set(jnp.asarray(sys_.mj_model.qpos0))
    u = jnp.zeros((3, sys_.nu))
    physics = sys_._mjx_physics  # the oracle's program: Jacobians of the batched step
    # JAX emits LAPACK as custom calls when it lowers (XLA adds none when it compiles), so
    # the lowered program answers without the fish's 20 s compile
    text = physics.jacobians_batch.lower(x, u).as_text()
    targets = set(re.findall(r"custom_call @([A-Za-z_0-9]+)", text))
    assert targets == set() or not [t for t in targets if "lapack" in t.lower()], targets
    assert "lapack" not in text.lower()
    # the check sees a LAPACK call where there is one
    chol = jax.jit(jax.vmap(jnp.linalg.cholesky)).lower(jnp.eye(3)[None].repeat(2, 0)).as_text()
    assert re.findall(r"custom_call @(lapack_[a-z]+_ffi)", chol)


ARM = (
    "<mujoco><worldbody><body><joint name='j' type='hinge'/><geom size='0.1'/></body></worldbody>"
    "<actuator><motor joint='j'/></actuator></mujoco>"
)


def test_a_system_is_kept_by_its_content_not_by_its_file(tmp_path):
    """Building the same model again gives the same System, so every program jitted on it
    is reused (a System is a static argument of jax.jit, hashed by identity): from the same
    file, from a copy elsewhere; an edited file, or other settings, give a new one."""
    path = tmp_path / "arm.xml"
    path.write_text(ARM)
    first = from_mjcf(str(path), backend="native")
    assert from_mjcf(str(path), backend="native") is first
    (tmp_path / "copy").mkdir()
    (tmp_path / "copy" / "arm.xml").write_text(ARM)
    assert from_mjcf(str(tmp_path / "copy" / "arm.xml"), backend="native") is first
    assert from_mjcf(str(path), backend="native", substeps=2) is not first
    path.write_text(ARM.replace("size='0.1'", "size='0.2'"))
    edited = from_mjcf(str(path), backend="native")
    assert edited is not first and float(edited.mj_model.geom_size[0, 0]) == 0.2
    rollout = jax.jit(lambda s, x0, U: s.rollout(x0, U), static_argnums=0)
    x0, U = jnp.zeros((1, 2)), jnp.ones((1, 3, 1))
    rollout(first, x0, U)
    size = rollout._cache_size()
    rollout(from_mjcf(str(tmp_path / "copy" / "arm.xml"), backend="native"), x0, U)
    assert rollout._cache_size() == size  # no new program for the same content
