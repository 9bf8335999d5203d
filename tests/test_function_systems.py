"""Black boxes that are not MuJoCo models (:mod:`mjx_surrogate.systems.function`): the
Lorenz and F-8 models against SciPy's integrator, D2C on them against the jacfwd oracle,
and a NumPy step behind the host callback against the same step in JAX."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from mjx_surrogate.control import chunked
from mjx_surrogate.control.ilqr import ILQRParams
from mjx_surrogate.identification.sysid import SysIdParams
from mjx_surrogate.runs import pipeline
from mjx_surrogate.systems import f8, lorenz
from mjx_surrogate.systems.function import from_jax, from_numpy

rng = np.random.default_rng(3)


def lorenz_rhs(x, u):
    return np.array([10 * (x[1] - x[0]) + u[0], x[0] * (28 - x[2]) - x[1], x[0] * x[1] - 8 / 3 * x[2]])


def f8_rhs(x, u):
    a, q, v, w = x[0], x[1], x[2], u[0]
    da = (-0.877 * a + v - 0.088 * a * v + 0.47 * a * a - 0.019 * q * q - a * a * v + 3.846 * a**3
          - 0.215 * w + 0.28 * a * a * w + 0.47 * a * w * w + 0.63 * w**3)  # fmt: skip
    dv = (
        -4.208 * a
        - 0.396 * v
        - 0.47 * a * a
        - 3.564 * a**3
        - 20.967 * w
        + 6.265 * a * a * w
        + 46 * a * w * w
        + 61.4 * w**3
    )
    return np.array([da, v, dv])


@pytest.mark.parametrize("mod,rhs,scale", [(lorenz, lorenz_rhs, 10.0), (f8, f8_rhs, 0.3)])
def test_steps_match_scipys_integrator(mod, rhs, scale):
    """One control step (u held) against solve_ivp at tolerance 1e-12, in float64."""
    s = mod.make_system()
    step = jax.jit(s.step)
    for _ in range(3):
        x, u = rng.normal(size=3) * scale, rng.normal(size=1) * 0.2
        ref = solve_ivp(lambda t, y: rhs(y, u), (0, s.dt), x, rtol=1e-12, atol=1e-12, method="DOP853").y[
            :, -1
        ]
        np.testing.assert_allclose(
            np.asarray(step(jnp.asarray(x), jnp.asarray(u))), ref, rtol=1e-7, atol=1e-7
        )


@pytest.mark.slow
def test_d2c_reaches_the_jacfwd_oracle_on_the_f8_through_the_api():
    """The F-8 preset's task from Python (the Lorenz preset runs from the command line in
    tests/test_function_cli.py): D2C (central differences, 1e-6, float64) converges to the
    exact oracle's cost within 0.01 %, reaches the goal and keeps the controls in their
    limits (saturated)."""
    s, task = f8.make_system(), f8.recovery_task()
    U0 = jnp.zeros((task.T, s.nu))
    params = ILQRParams(max_iter=200)
    d2c = chunked.solve(
        s, task, U0, jax.random.key(0), params, SysIdParams(1e-6, 1e-6, n_samples=8), "d2c"
    ).out
    exact = chunked.solve(s, task, U0, jax.random.key(0), params, SysIdParams(), "jacfwd").out
    metrics, _ = pipeline.summary(d2c, s, task)
    assert (
        metrics["status"] == "converged" and metrics["goal"]["reached"] and metrics["controls_within_limits"]
    )
    assert metrics["native_float64"] is None  # no MuJoCo model to replay on
    assert float(d2c.cost) == pytest.approx(float(exact.cost), rel=1e-4)  # -1.6e-5, saturated


def numpy_lorenz_step(x, u, dt=0.01, n=10):
    """The Lorenz preset's step written again in NumPy: classical RK4, u held."""
    h = dt / n
    for _ in range(n):
        k1 = lorenz_rhs(x, u)
        k2 = lorenz_rhs(x + h / 2 * k1, u)
        k3 = lorenz_rhs(x + h / 2 * k2, u)
        k4 = lorenz_rhs(x + h * k3, u)
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return x


@pytest.mark.parametrize("kw", [{}, {"threads": 2}])
def test_a_numpy_step_behind_the_callback_is_the_jax_step(kw):
    """Batched (vmap: one host call), inside jit, per-sample or in threads: the host path
    gives the JAX preset's numbers; vectorised NumPy too."""
    host = from_numpy(numpy_lorenz_step, 3, 1, 0.01, name="numpy_lorenz", **kw)
    vec = from_numpy(
        lambda X, U: np.stack([numpy_lorenz_step(x, u) for x, u in zip(X, U)]), 3, 1, 0.01, vectorized=True
    )
    ref = lorenz.make_system()
    X, U = jnp.asarray(rng.normal(size=(5, 3)) * 5), jnp.asarray(rng.normal(size=(5, 1)))
    want = jax.vmap(ref.step)(X, U)
    np.testing.assert_allclose(jax.jit(jax.vmap(host.step))(X, U), want, rtol=1e-12)
    np.testing.assert_allclose(jax.jit(jax.vmap(vec.step))(X, U), want, rtol=1e-12)
    np.testing.assert_allclose(host.step(X[0], U[0]), want[0], rtol=1e-12)
    rolled = jax.jit(host.rollout)(X[:2], jnp.ones((2, 4, 1)))
    np.testing.assert_allclose(rolled, jax.jit(ref.rollout)(X[:2], jnp.ones((2, 4, 1))), rtol=1e-12)


def test_a_host_function_has_no_exact_oracle():
    """D2C on a host function against central differences of it runs in
    docs/function_systems.md (tests/test_docs.py); the jacfwd oracle is refused, naming
    the field and the valid value."""
    host = from_numpy(numpy_lorenz_step, 3, 1, 0.01, name="numpy_lorenz")
    task = lorenz.switch_task(T=5)
    with pytest.raises(ms_config_error()) as err:
        chunked.solve(host, task, jnp.zeros((5, 1)), jax.random.key(0), ILQRParams(), SysIdParams(), "jacfwd")
    assert "experiment.oracle" in str(err.value) and "finite_difference" in str(err.value)


def ms_config_error():
    from mjx_surrogate.errors import ConfigError

    return ConfigError


def test_a_host_step_that_returns_nan_ends_diverged_and_a_wrong_shape_names_the_function():
    def blows_up(x, u):
        return np.full(3, np.nan) if abs(u[0]) > 0 else x

    bad = from_numpy(blows_up, 3, 1, 0.01, name="blows_up")
    task = lorenz.switch_task(T=5)
    out = chunked.solve(
        bad, task, jnp.ones((5, 1)), jax.random.key(0), ILQRParams(max_iter=3), SysIdParams(), "d2c"
    ).out
    metrics, _ = pipeline.summary(out, bad, task)
    assert metrics["status"] == "diverged" and metrics["cost"] is None
    short = from_numpy(lambda x, u: x[:2], 3, 1, 0.01, name="short_step")
    with pytest.raises(Exception, match=r"short_step returned shape \(2,\), expected \(3,\)"):
        jax.block_until_ready(jax.jit(short.step)(jnp.zeros(3), jnp.zeros(1)))


def test_a_jax_function_without_derivatives_and_bad_limits_are_refused():
    from mjx_surrogate.errors import ConfigError

    s = from_jax(lambda x, u: x + u, 1, 1, 0.1, differentiable=False)
    with pytest.raises(ConfigError, match="experiment.oracle"):
        s.exact_jacobians_batch
    with pytest.raises(ConfigError, match="system.u_min"):
        from_jax(lambda x, u: x + u, 1, 1, 0.1, u_min=1.0, u_max=-1.0)


def test_a_registered_black_box_is_built_once_per_name_and_mesh():
    """One cache, keyed by what the system is: the same name and mesh give the same object
    (its jitted programs reused), through the registry and through a config alike; a mesh
    gives a copy spread over it."""
    from jax.sharding import Mesh

    from mjx_surrogate import sharding
    from mjx_surrogate.runs.config import SystemConfig
    from mjx_surrogate.runs.resolution import build_system_from_config
    from mjx_surrogate.systems import registry

    plain = registry.make_function_system("lorenz")
    assert registry.make_function_system("lorenz") is plain and plain.mesh is None
    assert build_system_from_config(SystemConfig(name="lorenz")) is plain
    mesh = Mesh(np.asarray(jax.devices()), (sharding.AXIS,))  # every device (one here)
    spread = build_system_from_config(SystemConfig(name="lorenz"), mesh)
    assert spread is registry.make_function_system("lorenz", mesh) and spread is not plain
    assert spread.backend == "jax" and spread.mesh is mesh  # a JAX function: the whole mesh
    assert (spread.name, spread.nx, spread.nu, spread.dt) == (plain.name, plain.nx, plain.nu, plain.dt)
