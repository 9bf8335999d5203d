"""Native backend: MuJoCo C through ``mujoco.rollout``, called from jitted code.

The host call sits behind ``jax.pure_callback`` so a surrounding ``jit``/``vmap``/
``while_loop`` trace is unchanged; it is a true black box (no derivatives) and runs
every MuJoCo feature. Whole horizons go to C in one call, multi-threaded.

MuJoCo silently zeroes non-finite controls and resets a diverged state (``mj_resetData``,
which also resets ``time``); both are mapped to NaN states here so callers can reject them.
Host callbacks inside jitted while loops need synchronous CPU dispatch
(:func:`mjx_surrogate.runtime.configure_runtime`).
"""

from __future__ import annotations

import os
import queue

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

_SPEC = mujoco.mjtState.mjSTATE_FULLPHYSICS


class NativeSimulator:
    """Host-side batched simulator for one model; MjData are reused across calls.

    Calls may come concurrently (one per device when the batch is spread over a mesh,
    :mod:`mjx_surrogate.sharding`): each call takes a free set of MjData (making a new set
    only when all are in use), so concurrent calls run in parallel on their own data."""

    min_batch_per_thread = 32

    def __init__(self, mj_model: mujoco.MjModel, substeps: int, nthread: int | None = None):
        self.model = mj_model
        self.substeps = substeps
        self.nthread = max(1, nthread or os.cpu_count() or 1)
        self._free: queue.SimpleQueue = queue.SimpleQueue()
        self._free.put(self._new_datas())
        self.nx = mj_model.nq + mj_model.nv + mj_model.na
        data = mujoco.MjData(mj_model)
        self.template = np.empty(mujoco.mj_stateSize(mj_model, _SPEC))
        mujoco.mj_getState(mj_model, data, self.template, _SPEC)

    def _new_datas(self) -> list:
        return [mujoco.MjData(self.model) for _ in range(self.nthread)]

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
        # Small batches (a line search's few states per control step) run on this thread;
        # large ones on a thread pool made for the call. A persistent pool driven from
        # XLA's callback threads hung the process once in thousands of calls here.
        threaded = self.nthread > 1 and B >= self.min_batch_per_thread * self.nthread
        try:
            datas = self._free.get_nowait()
        except queue.Empty:
            datas = self._new_datas()
        try:
            state, _ = mj_rollout.rollout(self.model, datas if threaded else datas[0], init, ctrl)
        finally:
            self._free.put(datas)
        S = self.substeps
        X = np.empty((B, T + 1, self.nx))
        X[:, 0] = xb
        X[:, 1:] = state[:, S - 1 :: S, 1 : 1 + self.nx]
        # A reset (time going backwards) or a non-finite control poisons the rest.
        time = np.concatenate([init[:, :1], state[:, :, 0]], axis=1)
        reset = np.diff(time, axis=1) <= 0.0  # [B, T*S]
        bad_u = ~np.isfinite(ctrl).all(axis=-1)
        bad = np.logical_or.accumulate(reset | bad_u, axis=1)[:, S - 1 :: S]  # [B, T]
        X[:, 1:][bad] = np.nan
        return X.reshape(lead + (T + 1, self.nx)).astype(x0.dtype, copy=False)

    def closed_loop(self, x0, X_bar, U_bar, k, K, alphas, lo, hi):
        """u_t = clip(U_bar_t + alpha k_t + K_t (x_t - X_bar_t)) for every alpha at once:
        x0 [nx], X_bar [T+1, nx], U_bar, k [T, nu], K [T, nu, nx], alphas [A]
        -> X [A, T+1, nx], U [A, T, nu]."""
        x0, X_bar, U_bar, k, K, alphas, lo, hi = (
            np.asarray(a) for a in (x0, X_bar, U_bar, k, K, alphas, lo, hi)
        )
        T, nu = U_bar.shape
        A = len(alphas)
        X = np.empty((A, T + 1, self.nx))
        U = np.empty((A, T, nu))
        X[:, 0] = x0
        alphas = np.asarray(alphas, np.float64)[:, None]
        for t in range(T):
            u = U_bar[t] + alphas * k[t] + (X[:, t] - X_bar[t]) @ K[t].T
            U[:, t] = np.clip(u, lo, hi)
            X[:, t + 1] = self(X[:, t], U[:, t, None, :])[:, 1]
        dtype = x0.dtype
        with np.errstate(over="ignore"):  # a blown-up trial becomes inf: rejected as such
            return X.astype(dtype, copy=False), U.astype(dtype, copy=False)


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
        return jax.pure_callback(sim.closed_loop, out, *args, vmap_method="sequential")

    return closed_loop


def make_native_rollout(sim: NativeSimulator):
    """Jittable ``rollout(x0[B, nx], U[B, T, nu]) -> X[B, T+1, nx]`` through a callback."""

    def rollout(x0: jax.Array, U: jax.Array) -> jax.Array:
        T = U.shape[-2]
        out = jax.ShapeDtypeStruct(x0.shape[:-1] + (T + 1, sim.nx), x0.dtype)
        return jax.pure_callback(sim, out, x0, U.astype(x0.dtype), vmap_method="broadcast_all")

    return rollout


def make_native_step(sim: NativeSimulator):
    """Jittable ``step(x[nx], u[nu]) -> x_next[nx]``; vmaps into one batched host call."""
    rollout = make_native_rollout(sim)

    def step(x: jax.Array, u: jax.Array) -> jax.Array:
        return rollout(x, u[..., None, :])[..., 1, :]

    return step
