"""MJX backend: a pure, jittable, differentiable step built on ``mujoco.mjx``."""

from __future__ import annotations

import contextlib
import copy
import io
from typing import Callable, NamedTuple

import jax
import jax.numpy as jnp
import mujoco

from mjx_surrogate.errors import ConfigError
from mjx_surrogate.trajectory import simulate_batch


def import_mjx():
    """``mujoco.mjx``, imported on first use: it takes about 0.6 s (trimesh, scipy), which a
    native or function black box never needs. It prints "Failed to import warp" to stdout
    when the optional GPU Warp backend is absent, as expected on CPU: kept quiet."""
    with contextlib.redirect_stdout(io.StringIO()):
        from mujoco import mjx
    return mjx


def stepping_model(mj_model: mujoco.MjModel) -> mujoco.MjModel:
    """A copy of the model that MJX steps: no LAPACK custom calls, no sensors, no energy.

    jaxlib 0.10's CPU LAPACK kernels split a batch over XLA's intra-op thread pool and
    block on it; when the pool's threads all run such kernels at once (vmapped rollouts,
    ``jacfwd`` tangents), each waits for work only the others could do and the process
    deadlocks (seen on the fish, 2 cores; docs/performance.md). MJX's sparse mass-matrix
    path factors and solves M with its own loops, and its CG solver needs no Cholesky,
    so neither emits LAPACK. Same physics, to round-off (tests/test_systems.py).

    Sensors and energy only write ``sensordata`` and ``energy``, which the solver never
    reads (MJX runs no plugin or callback through which they could act): sensors switched
    off are not traced or compiled, and energy, which MJX refuses (dm_control's pendulum,
    cartpole and acrobot enable it), is not computed.
    """
    m = copy.copy(mj_model)
    m.opt.jacobian = mujoco.mjtJacobian.mjJAC_SPARSE
    if m.opt.solver == mujoco.mjtSolver.mjSOL_NEWTON:
        m.opt.solver = mujoco.mjtSolver.mjSOL_CG
    m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_SENSOR
    m.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_ENERGY)
    return m


class MjxUnsupported(ConfigError):
    """A model with a feature MJX lacks; ``reason`` is MJX's own word for it."""

    def __init__(self, field: str, reason: str):
        self.reason = reason
        super().__init__(field, f"MJX cannot simulate this model ({reason}); use 'native'")


def put_model(mj_model: mujoco.MjModel, device=None, field: str = "system.backend"):
    """``mjx.put_model`` of :func:`stepping_model`; a feature MJX lacks (a solver, a pair of
    colliding geom types, a plugin...) is :class:`MjxUnsupported` naming ``field``, not a
    traceback."""
    try:
        return import_mjx().put_model(stepping_model(mj_model), device=device)
    except Exception as exc:  # NotImplementedError mostly; any refusal of the model
        raise MjxUnsupported(field, " ".join(str(exc).split())[:200]) from None


class MjxPhysics(NamedTuple):
    """The MJX physics of one model and control step; every function jitted.

    step: ``(x[nx], u[nu]) -> x_next[nx]``, ``substeps`` physics steps.
    step_batch: ``(X [B, nx], U [B, nu]) -> [B, nx]``: the same numbers as ``vmap(step)``,
      traced as a loop over the substeps of the batched physics step (``vmap`` of the loop
      batches its body twice, to settle which carries are batched: twice the tracing).
    jacobians_batch: ``(X [B, nx], U [B, nu]) -> (A [B, nx, nx], B [B, nx, nu])``, the
      control step's exact Jacobians: forward mode along the nx + nu input directions,
      pushed through a loop over the substeps of the batched physics step (the state and
      the constraint solver's warmstart, which carries over from one substep to the next).
      The same numbers as ``vmap(jacfwd(step))`` (bit for bit in the tests, contacts
      included), traced faster for the reason above (``benchmarks/mjx_programs.py``,
      docs/performance.md).
    """

    step: Callable
    step_batch: Callable
    jacobians_batch: Callable


def make_mjx_physics(mj_model: mujoco.MjModel, substeps: int) -> MjxPhysics:
    """The :class:`MjxPhysics` of ``mj_model``, x = [qpos, qvel, act]. The MJX model is put
    on the device once, in the dtype that is active when this is called (float64 if
    ``jax_enable_x64`` is on)."""
    mjx = import_mjx()
    # Built eagerly even when first requested inside a trace (System.mjx_step is created
    # lazily): the model and data are constants of every program, never tracers.
    with jax.ensure_compile_time_eval():
        # On this process's own device: under jax.distributed, jax.devices()[0] may be
        # another process's.
        device = jax.local_devices()[0]
        model = put_model(mj_model, device=device)
        data0 = mjx.make_data(model, device=device)
    if jax.config.jax_enable_x64:
        # Under x64 some int32 fields come back from mjx.step as int64 (e.g. tendon
        # wrap data), which a loop carry rejects: start from the dtypes step returns.
        # Outside compile-time evaluation, where it would run every inner jit eagerly.
        out = jax.eval_shape(mjx.step, model, data0)
        with jax.ensure_compile_time_eval():
            data0 = jax.tree.map(lambda a, o: a.astype(o.dtype), data0, out)
    nq, nv, na = mj_model.nq, mj_model.nv, mj_model.na
    dtype = data0.qpos.dtype

    def put(data: mjx.Data, x: jax.Array, u: jax.Array) -> mjx.Data:
        x = x.astype(dtype)
        act = x[nq + nv :] if na else data.act
        return data.replace(qpos=x[:nq], qvel=x[nq : nq + nv], act=act, ctrl=u.astype(dtype))

    def state(data: mjx.Data) -> jax.Array:
        return jnp.concatenate([data.qpos, data.qvel] + ([data.act] if na else []))

    def physics_step(data: mjx.Data) -> mjx.Data:
        return mjx.step(model, data)

    def step(x: jax.Array, u: jax.Array) -> jax.Array:
        data = jax.lax.fori_loop(0, substeps, lambda _, d: physics_step(d), put(data0, x, u))
        return state(data)

    def batch_data(X: jax.Array, U: jax.Array) -> mjx.Data:
        data = jax.tree.map(lambda a: jnp.broadcast_to(a, X.shape[:1] + a.shape), data0)
        return jax.vmap(put)(data, X, U)

    def step_batch(X: jax.Array, U: jax.Array) -> jax.Array:
        data = batch_data(X, U)
        data = jax.lax.fori_loop(0, substeps, lambda _, d: jax.vmap(physics_step)(d), data)
        return jax.vmap(state)(data)

    def substep(x, w, u, data):
        """One physics step from state x, solver warmstart w [nv] and control u."""
        nxt = physics_step(put(data, x, u).replace(qacc_warmstart=w))
        return (state(nxt), nxt.qacc_warmstart), nxt

    def push(data, T_x, T_w, T_u):
        """One substep of one point, and the tangents [n, nx], [n, nv] of its state and
        warmstart along the n directions of (x0, u) pushed through it."""
        x, w, u = state(data), data.qacc_warmstart, data.ctrl
        f = lambda x, w, u: substep(x, w, u, data)  # noqa: E731
        tangent = lambda t_x, t_w, t_u: jax.jvp(f, (x, w, u), (t_x, t_w, t_u), has_aux=True)  # noqa: E731
        _, (T_x, T_w), nxt = jax.vmap(tangent, out_axes=(None, 0, None))(T_x, T_w, T_u)
        return nxt, T_x, T_w

    def jacobians_batch(X: jax.Array, U: jax.Array) -> tuple[jax.Array, jax.Array]:
        n, nx = X.shape
        nu = U.shape[1]
        eye = jnp.eye(nx + nu, dtype=dtype)  # directions: the nx state and nu control entries
        T_x = jnp.broadcast_to(eye[:, :nx], (n, nx + nu, nx))
        T_w = jnp.zeros((n, nx + nu, nv), dtype)  # the first warmstart is a constant
        T_u = eye[:, nx:]
        batch_push = jax.vmap(push, in_axes=(0, 0, 0, None))

        def body(_, carry):
            data, T_x, T_w = carry
            return batch_push(data, T_x, T_w, T_u)

        _, T_x, _ = jax.lax.fori_loop(0, substeps, body, (batch_data(X, U), T_x, T_w))
        J = jnp.swapaxes(T_x, 1, 2)  # [n, nx, nx + nu]
        return J[..., :nx], J[..., nx:]

    return MjxPhysics(jax.jit(step), jax.jit(step_batch), jax.jit(jacobians_batch))


def make_mjx_step(mj_model: mujoco.MjModel, substeps: int):
    """``step(x[nx], u[nu]) -> x_next[nx]`` of :func:`make_mjx_physics`."""
    return make_mjx_physics(mj_model, substeps).step


def make_mjx_rollout(step):
    """Batched rollout x0 [B, nx], U [B, T, nu] -> X [B, T+1, nx] over an MJX step."""

    def rollout(x0: jax.Array, U: jax.Array) -> jax.Array:
        return simulate_batch(step, x0, U)

    return rollout
