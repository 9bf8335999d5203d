"""Named host calls (``systems/host_call.py``): ``jax.pure_callback``'s results, under a
name XLA's persistent cache can keep, and the native simulator's key."""

import os
import subprocess
import sys
import textwrap

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from mjx_surrogate.systems import host_call
from mjx_surrogate.systems.backend_native import NativeSimulator

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _affine(x, u):
    return np.sin(x) + 2.0 * u[..., :1], np.sum(u, axis=-1)


def _out(x, u):
    lead = jnp.broadcast_shapes(x.shape[:-1], u.shape[:-1])
    return jax.ShapeDtypeStruct(lead + x.shape[-1:], x.dtype), jax.ShapeDtypeStruct(lead, u.dtype)


def _like(x):
    return jax.ShapeDtypeStruct(x.shape, x.dtype)


def _named(x, u):
    return host_call.call("test:affine", _affine, _out(x, u), x, u, vmap_method="broadcast_all")


def _plain(x, u):
    return jax.pure_callback(_affine, _out(x, u), x, u, vmap_method="broadcast_all")


@pytest.mark.parametrize("dtype", [jnp.float64, jnp.float32])
def test_named_call_gives_the_callbacks_results_in_jit_vmap_and_scan(dtype):
    assert host_call.available()
    x = jnp.arange(3.0, dtype=dtype) / 3
    U = jnp.linspace(-1, 1, 10, dtype=dtype).reshape(5, 2)
    X = jnp.stack([x, x + 1])

    def scanned(step):
        def run(x, U):
            return jax.lax.scan(lambda x, u: (step(x, u)[0], step(x, u)), x, U)[1]

        return jax.jit(run)

    for got, want in [
        (scanned(_named)(x, U), scanned(_plain)(x, U)),
        (jax.jit(jax.vmap(_named))(X, U[:2]), jax.vmap(_plain)(X, U[:2])),
    ]:
        for g, w in zip(got, want):
            assert g.dtype == w.dtype == dtype and g.shape == w.shape
            np.testing.assert_array_equal(np.asarray(g), np.asarray(w))
    hlo = jax.jit(_named).lower(x, U[0]).as_text()
    assert host_call.TARGET in hlo and "test:affine" in hlo


def test_sequential_vmap_calls_once_per_row():
    rows = []

    def record(x):
        rows.append(x.shape)
        return x * 2

    f = jax.jit(
        jax.vmap(
            lambda x: host_call.call(
                "test:rows", record, jax.ShapeDtypeStruct(x.shape, x.dtype), x, vmap_method="sequential"
            )
        )
    )
    np.testing.assert_array_equal(np.asarray(f(jnp.ones((3, 4)))), 2 * np.ones((3, 4)))
    assert rows == [(4,)] * 3


def test_an_exception_in_the_host_function_reaches_the_caller_with_its_message():
    def broken(x):
        raise RuntimeError("the simulator refused")

    f = jax.jit(
        lambda x: host_call.call(
            "test:broken", broken, jax.ShapeDtypeStruct(x.shape, x.dtype), x, vmap_method="sequential"
        )
    )
    with pytest.raises(Exception, match="RuntimeError: the simulator refused"):
        f(jnp.ones(2)).block_until_ready()


def test_the_first_function_registered_under_a_key_stays():
    first = host_call.register("test:first", np.negative)
    assert host_call.register("test:first", np.positive) is first is np.negative


def test_the_simulators_key_is_its_models_content():
    xml = (
        '<mujoco><worldbody><body><joint name="j" type="hinge"/><geom size=".1" mass="1"/></body></worldbody>'
    )
    xml += '<actuator><motor joint="j"/></actuator></mujoco>'
    m = mujoco.MjModel.from_xml_string(xml)
    key = NativeSimulator(m, 2).key
    assert NativeSimulator(mujoco.MjModel.from_xml_string(xml), 2).key == key
    assert NativeSimulator(m, 3).key != key
    m.opt.timestep *= 2
    assert NativeSimulator(m, 2).key != key


_SCRIPT = textwrap.dedent(
    """
    import sys, jax, jax.numpy as jnp
    from jax import monitoring
    from mjx_surrogate.runtime import configure_runtime
    configure_runtime(x64=True, compile_cache=sys.argv[1])
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0)
    hits = []
    monitoring.register_event_listener(lambda e, **kw: hits.append(e) if e.endswith("cache_hits") else None)
    from mjx_surrogate.systems import make_system
    s = make_system("pendulum", backend="native")
    X = jax.jit(s.rollout)(jnp.zeros((2, s.nx)), jnp.ones((2, 7, s.nu)) * 0.1)
    print(len(hits), float(X.sum()).hex())
    """
)


@pytest.mark.slow  # over 5 s: the fast tier's budget
def test_a_native_rollouts_program_is_loaded_from_the_cache_by_a_new_process(tmp_path):
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTEST_XDIST", "PYTEST_ADDOPTS"))}
    script = tmp_path / "run.py"
    script.write_text(_SCRIPT)

    def run():
        out = subprocess.run(
            [sys.executable, str(script), str(tmp_path / "cache")],
            cwd=ROOT,
            env=env,
            capture_output=True,
            text=True,
        )
        assert out.returncode == 0, out.stderr[-2000:]
        hits, total = out.stdout.split()
        return int(hits), total

    (first, total), (second, again) = run(), run()
    assert first == 0 and second >= 1 and again == total
    assert any(f.startswith("jit_rollout") for f in os.listdir(tmp_path / "cache"))


def test_a_native_solves_programs_and_point_goals_hold_no_python_callback():
    """Every host call of a native solve (the simulator; native kinematics for point
    goals) is named, so the whole program can be cached."""
    from mjx_surrogate.control import chunked
    from mjx_surrogate.control.ilqr import ILQRParams
    from mjx_surrogate.identification.sysid import SysIdParams
    from mjx_surrogate.runs.config import Config, SystemConfig, TaskConfig
    from mjx_surrogate.runs.resolution import resolve
    from mjx_surrogate.systems.kinematics import native_points_fn

    cfg = Config(
        system=SystemConfig(name="pendulum", backend="native"), task=TaskConfig(preset="pendulum_d2c", T=10)
    )
    _, system, task = resolve(cfg)
    U0, key, P, SID = (
        jnp.zeros((10, system.nu)),
        jax.random.key(0),
        ILQRParams(max_iter=3),
        SysIdParams(n_samples=6),
    )
    state, _ = jax.eval_shape(lambda: chunked.start(system, task, U0, key, P, SID, "d2c"))
    points = native_points_fn(system.mj_model, [("body", 1)])
    texts = [
        chunked.start.lower(system, task, U0, key, P, SID, "d2c").as_text(),
        chunked.advance.lower(
            system, task, state, jnp.asarray(1), jnp.asarray(False), P, SID, "d2c"
        ).as_text(),
        jax.jit(jax.jacfwd(points)).lower(jnp.zeros(system.nx)).as_text(),
    ]
    for text in texts:
        assert host_call.TARGET in text and "python_cpu_callback" not in text
