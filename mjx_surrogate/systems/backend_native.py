"""Native backend: MuJoCo C through ``mujoco.rollout``, called from jitted code.

The host call sits behind :func:`mjx_surrogate.systems.host_call.call` (a named XLA
custom call keyed by the simulated model's content, so its programs enter JAX's
persistent compilation cache) so a surrounding ``jit``/``vmap``/``while_loop`` trace is
unchanged; it is a true black box (no derivatives) and runs
every MuJoCo feature. Whole horizons go to C in one call, multi-threaded; the line
search's feedback rollouts go one control step per ``mujoco.batch`` call.

MuJoCo silently zeroes a non-finite control and resets a diverged state; the simulator
turns its automatic reset off and maps both to NaN states, so callers can reject them.
Host callbacks inside jitted while loops need synchronous CPU dispatch
(:func:`mjx_surrogate.runtime.configure_runtime`).
"""

from __future__ import annotations

import contextlib
import copy
import hashlib
import os
import queue
from typing import NamedTuple

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import batch as mj_batch
from mujoco import rollout as mj_rollout

from mjx_surrogate.systems import host_call

_SPEC = mujoco.mjtState.mjSTATE_FULLPHYSICS
_ROW = mujoco.mjtState.mjSTATE_INTEGRATION
# MuJoCo's global callbacks that run after the position and velocity sensors of a step
# (mj_forward's order) and may read them to change the motion.
_CALLBACKS_AFTER_SENSORS = ("control", "passive", "act_dyn", "act_gain", "act_bias")


def outputs_can_act(mj_model: mujoco.MjModel) -> bool:
    """Whether the model's sensors or energy can change its motion: through a plugin (its
    computations and state advance with the sensor stage) or an installed MuJoCo callback
    that runs after them. Otherwise they only write ``sensordata`` and ``energy``, which the
    solver never reads."""
    if mj_model.nplugin > 0:
        return True
    return any(getattr(mujoco, f"get_mjcb_{name}")() is not None for name in _CALLBACKS_AFTER_SENSORS)


def model_key(mj_model: mujoco.MjModel, *extra) -> str:
    """A name for host calls on ``mj_model`` (:mod:`~mjx_surrogate.systems.host_call`): a
    digest of the model's bytes (options and flags included) and of ``extra``."""
    buf = np.empty(mujoco.mj_sizeModel(mj_model), np.uint8)
    mujoco.mj_saveModel(mj_model, None, buf)
    digest = hashlib.sha256(buf.tobytes())
    digest.update(repr(extra).encode())
    return f"mujoco-{digest.hexdigest()[:32]}"


def _diverged(a: np.ndarray) -> np.ndarray:
    """[..., n] -> [...]: any entry non-finite or beyond ``mjMAXVAL``, MuJoCo's own test for
    a bad state or control (two reductions, no temporary of a's size: NaN propagates)."""
    with np.errstate(invalid="ignore"):
        return ~((a.max(axis=-1) <= mujoco.mjMAXVAL) & (a.min(axis=-1) >= -mujoco.mjMAXVAL))


class _StepBuffers(NamedTuple):
    """Inputs and outputs of one batch size's one-step ``mujoco.rollout`` call, reused."""

    models: list  # the model, once per row
    init: np.ndarray  # [B, nstate]: the template, x written per call
    ctrl: np.ndarray  # [B, substeps, nu]
    state: np.ndarray  # [B, substeps, nstate]
    sensordata: np.ndarray  # [B, substeps, nsensordata]: the model's sensors (unused)


class NativeSimulator:
    """Host-side batched simulator for one model; MjData are reused across calls.

    The simulator steps a copy of the model with MuJoCo's automatic reset off: a diverged
    state stays diverged instead of being silently replaced by the initial state (which a
    one-step call from time 0 could not tell apart from a real step). The copy's sensors
    and energy are off too unless they can change the motion (:func:`outputs_can_act`,
    checked when the simulator is made): the states are those of ``mj_step`` with them on,
    bit for bit, at less cost (range finders can cost more than the physics).

    A control step whose control or resulting state is non-finite or beyond ``mjMAXVAL``
    (MuJoCo would zero such a control), and every step after it, is returned as NaN so that
    callers reject it.

    Calls may come concurrently (one per device when the batch is spread over a mesh,
    :mod:`mjx_surrogate.sharding`): each call takes a free set of MjData, or a free line-search batch
    (making new ones only when all are in use), so concurrent calls run in parallel on
    their own data."""

    min_batch_per_thread = 32

    def __init__(self, mj_model: mujoco.MjModel, substeps: int, nthread: int | None = None):
        self.model = copy.copy(mj_model)
        self.model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_AUTORESET
        if not outputs_can_act(mj_model):
            self.model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_SENSOR
            self.model.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_ENERGY)
        self.substeps = substeps
        self.nthread = max(1, nthread or os.cpu_count() or 1)
        self._free: queue.SimpleQueue = queue.SimpleQueue()
        self._free.put(self._new_datas())
        self.nx = mj_model.nq + mj_model.nv + mj_model.na
        data = mujoco.MjData(self.model)
        self.template = np.empty(mujoco.mj_stateSize(self.model, _SPEC))
        mujoco.mj_getState(self.model, data, self.template, _SPEC)
        # The line search's batch rows (mjSTATE_INTEGRATION): the template's values, with
        # x at columns 1 : 1 + nx as in ``template`` and the controls after the warmstart.
        self._row_template = np.empty(mujoco.mj_stateSize(self.model, _ROW))
        mujoco.mj_getState(self.model, data, self._row_template, _ROW)
        self._ctrl_col = mujoco.mj_stateSize(self.model, int(mujoco.mjtState.mjSTATE_CTRL) - 1)
        self._batches: dict[int, queue.SimpleQueue] = {}  # free batches by size
        self._step_buffers: dict[int, queue.SimpleQueue] = {}  # free one-step buffers by size
        # what determines its results: the stepped model, the substeps, the thread count
        self.key = model_key(self.model, "simulator", substeps, self.nthread)

    def _new_datas(self) -> list:
        return [mujoco.MjData(self.model) for _ in range(self.nthread)]

    @contextlib.contextmanager
    def _datas(self, B: int):
        """A free set of MjData for a ``mujoco.rollout`` of B rows: one per thread, or one
        for a small batch, which runs on the calling thread. (A persistent pool driven from
        XLA's callback threads hung the process once in thousands of calls here, so large
        batches get a thread pool made for the call.)"""
        try:
            datas = self._free.get_nowait()
        except queue.Empty:
            datas = self._new_datas()
        try:
            yield datas if self.nthread > 1 and B >= self.min_batch_per_thread * self.nthread else datas[:1]
        finally:
            self._free.put(datas)

    def __call__(self, x0: np.ndarray, U: np.ndarray) -> np.ndarray:
        """x0 [..., nx], U [..., T, nu] (float) -> X [..., T+1, nx] in x0's dtype."""
        x0 = np.asarray(x0)
        U = np.asarray(U)
        lead = x0.shape[:-1]
        T, nu = U.shape[-2:]
        U = np.broadcast_to(U, lead + (T, nu))
        xb = x0.reshape(-1, self.nx).astype(np.float64)
        ub = U.reshape(-1, T, nu).astype(np.float64)
        B = xb.shape[0]
        init = np.tile(self.template, (B, 1))
        init[:, 1 : 1 + self.nx] = xb
        ctrl = np.repeat(ub, self.substeps, axis=1)
        with self._datas(B) as datas:
            state, _ = mj_rollout.rollout(self.model, datas, init, ctrl)
        S = self.substeps
        X = np.empty((B, T + 1, self.nx))
        X[:, 0] = xb
        X[:, 1:] = state[:, S - 1 :: S, 1 : 1 + self.nx]
        bad = np.logical_or.accumulate(_diverged(ub) | _diverged(X[:, 1:]), axis=1)  # [B, T]
        X[:, 1:][bad] = np.nan
        return X.reshape(lead + (T + 1, self.nx)).astype(x0.dtype, copy=False)

    def step(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """One control step of every row: x [..., nx], u [..., nu] -> x_next [..., nx] in x's
        dtype; the numbers of :meth:`__call__` with T = 1 (bit for bit), with its inputs and
        outputs reused across calls of the same batch size and MuJoCo's argument checks
        skipped (the identification's one-step batches: tens of thousands of rows)."""
        x, u = np.asarray(x), np.asarray(u)
        lead = np.broadcast_shapes(x.shape[:-1], u.shape[:-1])
        nx, nu, S = self.nx, u.shape[-1], self.substeps
        xb = np.broadcast_to(x, lead + (nx,)).reshape(-1, nx)
        ub = np.broadcast_to(u, lead + (nu,)).reshape(-1, nu)
        B = xb.shape[0]
        buf = self._take_step_buffers(B, nu)
        try:
            buf.init[:, 1 : 1 + nx] = xb
            buf.ctrl[:] = ub[:, None, :]
            with self._datas(B) as datas:
                mj_rollout.rollout(
                    buf.models,
                    datas,
                    buf.init,
                    buf.ctrl,
                    skip_checks=True,
                    nstep=S,
                    state=buf.state,
                    sensordata=buf.sensordata,
                )
            out = buf.state[:, S - 1, 1 : 1 + nx].astype(x.dtype)
        finally:
            self._step_buffers[B].put(buf)
        bad = _diverged(ub) | _diverged(out)
        if bad.any():
            out[bad] = np.nan
        return out.reshape(lead + (nx,))

    def _take_step_buffers(self, B: int, nu: int) -> _StepBuffers:
        """Free one-step buffers for B rows (made when none is free: concurrent calls
        each get their own)."""
        try:
            return self._step_buffers.setdefault(B, queue.SimpleQueue()).get_nowait()
        except queue.Empty:
            S, nstate = self.substeps, self.template.size
            init = np.tile(self.template, (B, 1))
            sensors = np.empty((B, S, self.model.nsensordata))
            return _StepBuffers(
                [self.model] * B, init, np.empty((B, S, nu)), np.empty((B, S, nstate)), sensors
            )

    def closed_loop(self, x0, X_bar, U_bar, k, K, alphas, lo, hi):
        """u_t = clip(U_bar_t + alpha k_t + K_t (x_t - X_bar_t)) for every alpha at once:
        x0 [nx], X_bar [T+1, nx], U_bar, k [T, nu], K [T, nu, nx], alphas [A]
        -> X [A, T+1, nx], U [A, T, nu].

        One ``mujoco.batch.Batch`` call per control step steps all step sizes on MuJoCo's
        own threads. Each control step starts from the full-physics template holding x_t,
        the numbers of :meth:`__call__` (bit for bit). A trial MuJoCo raises an error on
        is marked diverged, like one that leaves ``mjMAXVAL``."""
        dtype = np.asarray(x0).dtype
        x0, X_bar, U_bar, k, K, alphas, lo, hi = (
            np.asarray(a, np.float64) for a in (x0, X_bar, U_bar, k, K, alphas, lo, hi)
        )
        T, nu = U_bar.shape
        A, nx, S = len(alphas), self.nx, self.substeps
        X = np.empty((A, T + 1, nx))
        U = np.empty((A, T, nu))
        X[:, 0] = x0
        V = U_bar + alphas[:, None, None] * k  # [A, T, nu]
        KT = np.swapaxes(K, 1, 2)  # [T, nx, nu]
        clip = bool(np.isfinite(lo).any() or np.isfinite(hi).any())
        raised = np.zeros((A, T), bool)
        dx = np.empty((A, nx))
        batch = self._take_batch(A)
        rows, ctrl = batch.state, slice(self._ctrl_col, self._ctrl_col + nu)
        try:
            with np.errstate(invalid="ignore", over="ignore"):
                for t in range(T):  # ufuncs into buffers: np.clip costs more than the physics
                    u = U[:, t]
                    np.subtract(X[:, t], X_bar[t], out=dx)
                    np.matmul(dx, KT[t], out=u)
                    np.add(u, V[:, t], out=u)
                    if clip:
                        np.maximum(u, lo, out=u)
                        np.minimum(u, hi, out=u)
                    rows[:] = self._row_template
                    rows[:, 1 : 1 + nx] = X[:, t]
                    rows[:, ctrl] = u
                    try:
                        batch.step(nstep=S)
                    except mj_batch.SimulationError as e:
                        raised[e.ids, t] = True
                    X[:, t + 1] = rows[:, 1 : 1 + nx]
        finally:
            self._batches[A].put(batch)
        with np.errstate(invalid="ignore"):
            bad = np.logical_or.accumulate(raised | _diverged(U) | _diverged(X[:, 1:]), axis=1)  # [A, T]
        X[:, 1:][bad] = np.nan
        with np.errstate(over="ignore"):  # a blown-up trial becomes inf: rejected as such
            return X.astype(dtype, copy=False), U.astype(dtype, copy=False)

    def _take_batch(self, nsim: int) -> mj_batch.Batch:
        """A free batch of ``nsim`` simulations on up to ``nthread`` threads (made when
        none is free: concurrent calls each get their own)."""
        try:
            return self._batches.setdefault(nsim, queue.SimpleQueue()).get_nowait()
        except queue.Empty:
            return mj_batch.Batch(self.model, nsim, nthread=min(self.nthread, nsim))


def make_native_closed_loop(sim: NativeSimulator):
    """Jittable ``ilqr.ClosedLoopFn``: the whole line-search forward pass in one host call."""

    def closed_loop(x0, X_bar, U_bar, k, K, alphas, lo, hi):
        T, nu = U_bar.shape
        dt = x0.dtype
        out = (
            jax.ShapeDtypeStruct((alphas.shape[0], T + 1, sim.nx), dt),
            jax.ShapeDtypeStruct((alphas.shape[0], T, nu), dt),
        )
        args = [
            a.astype(dt)
            for a in (
                x0,
                X_bar,
                U_bar,
                k,
                K,
                alphas,
                jnp.broadcast_to(lo, (nu,)),
                jnp.broadcast_to(hi, (nu,)),
            )
        ]
        return host_call.call(f"{sim.key}/closed_loop", sim.closed_loop, out, *args, vmap_method="sequential")

    return closed_loop


def make_native_rollout(sim: NativeSimulator):
    """Jittable ``rollout(x0[B, nx], U[B, T, nu]) -> X[B, T+1, nx]`` through a callback."""

    def rollout(x0: jax.Array, U: jax.Array) -> jax.Array:
        T = U.shape[-2]
        out = jax.ShapeDtypeStruct(x0.shape[:-1] + (T + 1, sim.nx), x0.dtype)
        U = U.astype(x0.dtype)
        return host_call.call(f"{sim.key}/rollout", sim, out, x0, U, vmap_method="broadcast_all")

    return rollout


def make_native_step(sim: NativeSimulator):
    """Jittable ``step(x[nx], u[nu]) -> x_next[nx]``; vmaps into one batched host call."""

    def step(x: jax.Array, u: jax.Array) -> jax.Array:
        out = jax.ShapeDtypeStruct(jnp.broadcast_shapes(x.shape[:-1], u.shape[:-1]) + (sim.nx,), x.dtype)
        u = u.astype(x.dtype)
        return host_call.call(f"{sim.key}/step", sim.step, out, x, u, vmap_method="broadcast_all")

    return step
