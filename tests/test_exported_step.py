"""The MJX step's disk-cached exported programs (mjx_surrogate/systems/exported_step.py)."""

import functools
import os

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mjx_surrogate.systems import exported_step


@functools.cache
def _pendulum_reference():
    """The pendulum at 2 substeps, native, and ``vmap(jacfwd)`` of its plain MJX step, jitted
    once for the tests below (the program takes about 6 s to build)."""
    from mjx_surrogate.systems import backend_mjx, system
    from mjx_surrogate.systems.registry import default_config

    xml = default_config("pendulum").xml()
    model = system.build_system("pendulum", xml, 2, "native").mj_model
    plain = backend_mjx.make_mjx_step(model, 2)
    return xml, plain, jax.jit(jax.vmap(jax.jacfwd(plain, argnums=(0, 1))))


def _inputs(system, n=7):
    k = jax.random.split(jax.random.key(0), 2)
    return 0.3 * jax.random.normal(k[0], (n, system.nx)), jax.random.normal(k[1], (n, system.nu))


@pytest.mark.slow
def test_exported_step_gives_the_plain_steps_numbers_batched_nested_in_scans(systems, tmp_path, monkeypatch):
    monkeypatch.setattr(exported_step, "cache_folder", lambda: str(tmp_path))
    s = systems("pendulum", "mjx")
    plain = s.mjx_step
    cached = exported_step.with_exported_batches(plain, s.mj_model, s.substeps)
    x, u = _inputs(s)
    np.testing.assert_array_equal(jax.jit(jax.vmap(cached))(x, u), jax.jit(jax.vmap(plain))(x, u))
    np.testing.assert_array_equal(jax.jit(cached)(x[0], u[0]), jax.jit(plain)(x[0], u[0]))
    xs = jnp.stack([x, x + 0.1, x - 0.1])  # a vmap around a vmap, u shared by the outer one
    nested = [jax.jit(jax.vmap(jax.vmap(f), in_axes=(0, None))) for f in (cached, plain)]
    np.testing.assert_array_equal(nested[0](xs, u), nested[1](xs, u))
    U = jnp.broadcast_to(u[:, None], (7, 4, s.nu))

    def rollouts(step):
        return jax.jit(jax.vmap(lambda x0, Ut: jax.lax.scan(lambda c, ut: (step(c, ut), c), x0, Ut)[1]))

    np.testing.assert_array_equal(rollouts(cached)(x, U), rollouts(plain)(x, U))
    assert len(os.listdir(tmp_path)) == 3  # programs for [nx], [7, nx] and [21, nx]


@pytest.mark.slow
def test_a_second_wrapper_loads_the_programs_without_tracing_the_step(systems, tmp_path, monkeypatch):
    monkeypatch.setattr(exported_step, "cache_folder", lambda: str(tmp_path))
    s = systems("pendulum", "mjx")
    traced = []

    def step(x, u):  # counts its traces
        traced.append(1)
        return s.mjx_step(x, u)

    x, u = _inputs(s, 5)
    first = jax.jit(jax.vmap(exported_step.with_exported_batches(step, s.mj_model, s.substeps)))(x, u)
    files = len(os.listdir(tmp_path))
    assert traced and files >= 1
    traced.clear()
    second = jax.jit(jax.vmap(exported_step.with_exported_batches(step, s.mj_model, s.substeps)))(x, u)
    assert not traced
    np.testing.assert_array_equal(first, second)
    # another model (here: other substeps) never reads that program
    other = exported_step.with_exported_batches(step, s.mj_model, s.substeps + 1)
    jax.jit(jax.vmap(other))(x, u)
    assert traced and len(os.listdir(tmp_path)) > files


@pytest.mark.slow
def test_nothing_is_written_with_the_compilation_cache_off(systems, monkeypatch):
    monkeypatch.setattr(exported_step, "cache_folder", lambda: None)
    s = systems("pendulum", "mjx")
    x, u = _inputs(s, 3)
    out = jax.jit(jax.vmap(exported_step.with_exported_batches(s.mjx_step, s.mj_model, s.substeps)))(x, u)
    np.testing.assert_array_equal(out, jax.jit(jax.vmap(s.mjx_step))(x, u))


@pytest.mark.slow
def test_exported_jacobians_are_jacfwd_through_the_plain_step_and_step_stays_differentiable(systems):
    from mjx_surrogate.identification import sysid

    s = systems("pendulum", "mjx")
    x, u = _inputs(s, 4)
    X = jnp.concatenate([x, x[:1]])
    A, B = jax.jit(jax.vmap(s.mjx_jacobians))(x, u)
    A_ref, B_ref = jax.jit(lambda X, U: sysid.exact_jacobians(s.mjx_step, X, U))(X, u)
    np.testing.assert_allclose(A, A_ref, rtol=0, atol=1e-12)
    np.testing.assert_allclose(B, B_ref, rtol=0, atol=1e-12)
    A2, B2 = jax.jit(jax.vmap(jax.jacfwd(s.step, argnums=(0, 1))))(x, u)  # the exported step
    np.testing.assert_allclose(A2, A_ref, rtol=0, atol=1e-12)
    np.testing.assert_allclose(B2, B_ref, rtol=0, atol=1e-12)


@pytest.mark.slow
def test_a_native_systems_oracle_loads_its_programs_without_building_the_mjx_model(tmp_path, monkeypatch):
    """A native system's MJX step and Jacobians (its exact oracle) are exported too, and a
    later system of the same model runs them from disk without building the MJX model."""
    from mjx_surrogate.systems import backend_mjx, system

    xml, plain, reference = _pendulum_reference()
    monkeypatch.setattr(exported_step, "cache_folder", lambda: str(tmp_path))

    def fresh():  # not a System kept from before: a later run's, in a new process
        system.forget_systems()
        return system.build_system("pendulum", xml, 2, "native")

    first = fresh()
    x, u = _inputs(first, 5)
    step = jax.jit(jax.vmap(first.mjx_step))(x, u)
    A, B = jax.jit(jax.vmap(first.mjx_jacobians))(x, u)
    np.testing.assert_array_equal(step, jax.jit(jax.vmap(plain))(x, u))
    A_ref, B_ref = reference(x, u)
    np.testing.assert_allclose(A, A_ref, rtol=0, atol=1e-12)  # the chain rule over substeps
    np.testing.assert_allclose(B, B_ref, rtol=0, atol=1e-12)
    assert len(os.listdir(tmp_path)) == 4  # step and Jacobians, each for [nx] and [5, nx]

    def no_model(*args):
        raise AssertionError("the MJX model was built")

    monkeypatch.setattr(backend_mjx, "make_mjx_physics", no_model)
    second = fresh()
    np.testing.assert_array_equal(jax.jit(jax.vmap(second.mjx_step))(x, u), step)
    np.testing.assert_array_equal(jax.jit(jax.vmap(second.mjx_jacobians))(x, u)[0], A)


@pytest.mark.slow
def test_the_batch_jacobians_export_only_the_batchs_program(tmp_path, monkeypatch):
    """The exact oracle's batched Jacobians (``System.mjx_jacobians_batch``) write one
    program, the batch's: ``vmap`` of the per-point function exports the unbatched one too."""
    from mjx_surrogate.systems import system

    xml, _, reference = _pendulum_reference()  # the plain step of the same model and substeps
    monkeypatch.setattr(exported_step, "cache_folder", lambda: str(tmp_path))
    system.forget_systems()  # a System built afresh, its programs not yet exported
    s = system.build_system("pendulum", xml, 2, "native")
    x, u = _inputs(s, 5)
    A, B = jax.jit(s.mjx_jacobians_batch)(x, u)
    assert len(os.listdir(tmp_path)) == 1
    A_ref, B_ref = reference(x, u)
    np.testing.assert_allclose(A, A_ref, rtol=0, atol=1e-12)  # the chain rule over substeps
    np.testing.assert_allclose(B, B_ref, rtol=0, atol=1e-12)
    # under an outer vmap (a multi-start oracle) the batches merge into one program
    A2, _ = jax.jit(jax.vmap(s.mjx_jacobians_batch))(jnp.stack([x, -x]), jnp.stack([u, u]))
    np.testing.assert_allclose(A2[0], A, rtol=0, atol=1e-12)  # another batch size: round-off
    assert len(os.listdir(tmp_path)) == 2
