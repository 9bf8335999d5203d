"""MJX backend: a pure, jittable, differentiable step built on ``mujoco.mjx``."""

from __future__ import annotations

import contextlib
import copy
import io

import jax
import jax.numpy as jnp
import mujoco

# mujoco.mjx prints "Failed to import warp" to stdout when the optional GPU Warp backend
# is absent; that is expected on CPU, so this one import is kept quiet.
with contextlib.redirect_stdout(io.StringIO()):
    from mujoco import mjx

from mjx_surrogate.trajectory import simulate_batch


def _without_batched_lapack(mj_model: mujoco.MjModel) -> mujoco.MjModel:
    """A copy of the model that MJX steps without LAPACK custom calls.

    jaxlib 0.10's CPU LAPACK kernels split a batch over XLA's intra-op thread pool and
    block on it; when the pool's threads all run such kernels at once (vmapped rollouts,
    ``jacfwd`` tangents), each waits for work only the others could do and the process
    deadlocks (seen on the fish, 2 cores; docs/performance.md). MJX's sparse mass-matrix
    path factors and solves M with its own loops, and its CG solver needs no Cholesky,
    so neither emits LAPACK. Same physics, to round-off (tests/test_systems.py).
    """
    m = copy.copy(mj_model)
    m.opt.jacobian = mujoco.mjtJacobian.mjJAC_SPARSE
    if m.opt.solver == mujoco.mjtSolver.mjSOL_NEWTON:
        m.opt.solver = mujoco.mjtSolver.mjSOL_CG
    return m


def make_mjx_step(mj_model: mujoco.MjModel, substeps: int):
    """Return ``step(x[nx], u[nu]) -> x_next[nx]`` advancing ``substeps`` physics steps.

    x = [qpos, qvel, act]. The MJX model is put on the device once, in the dtype that
    is active when this is called (float64 if ``jax_enable_x64`` is on).
    """
    # Built eagerly even when first requested inside a trace (System.mjx_step is created
    # lazily): the model and data are constants of every program, never tracers.
    with jax.ensure_compile_time_eval():
        # On this process's own device: under jax.distributed, jax.devices()[0] may be
        # another process's.
        device = jax.local_devices()[0]
        model = mjx.put_model(_without_batched_lapack(mj_model), device=device)
        data0 = mjx.make_data(model, device=device)
    if jax.config.jax_enable_x64:
        # Under x64 some int32 fields come back from mjx.step as int64 (e.g. tendon
        # wrap data), which a loop carry rejects: start from the dtypes step returns.
        # Outside compile-time evaluation, where it would run every inner jit eagerly
        # (fish: 16.6 s against 1.4 s).
        out = jax.eval_shape(mjx.step, model, data0)
        with jax.ensure_compile_time_eval():
            data0 = jax.tree.map(lambda a, o: a.astype(o.dtype), data0, out)
    nq, nv, na = mj_model.nq, mj_model.nv, mj_model.na

    def step(x: jax.Array, u: jax.Array) -> jax.Array:
        dtype = data0.qpos.dtype
        x = x.astype(dtype)
        data = data0.replace(
            qpos=x[:nq],
            qvel=x[nq : nq + nv],
            act=x[nq + nv :] if na else data0.act,
            ctrl=u.astype(dtype),
        )
        data = jax.lax.fori_loop(0, substeps, lambda _, d: mjx.step(model, d), data)
        parts = [data.qpos, data.qvel] + ([data.act] if na else [])
        return jnp.concatenate(parts)

    return jax.jit(step)


def make_mjx_rollout(step):
    """Batched rollout x0 [B, nx], U [B, T, nu] -> X [B, T+1, nx] over an MJX step."""

    def rollout(x0: jax.Array, U: jax.Array) -> jax.Array:
        return simulate_batch(step, x0, U)

    return rollout
