"""Native backend: MuJoCo C through ``mujoco.rollout``, called from jitted code.

The host call sits behind ``jax.pure_callback`` so a surrounding ``jit``/``vmap``/
``while_loop`` trace is unchanged; it is a true black box (no derivatives) and runs
every MuJoCo feature. Whole horizons go to C in one call, multi-threaded.

MuJoCo silently zeroes a non-finite control and resets a diverged state; the simulator
turns its automatic reset off and maps both to NaN states, so callers can reject them.
Host callbacks inside jitted while loops need synchronous CPU dispatch
(:func:`mjx_surrogate.runtime.configure_runtime`).
"""

from __future__ import annotations

import copy
import functools
import os
import queue
import time
from concurrent.futures import ThreadPoolExecutor
from contextlib import nullcontext

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

_SPEC = mujoco.mjtState.mjSTATE_FULLPHYSICS


def _diverged(a: np.ndarray) -> np.ndarray:
    """[..., n] -> [...]: any entry non-finite or beyond ``mjMAXVAL``, MuJoCo's own test for
    a bad state or control."""
    return ~(np.abs(a) <= mujoco.mjMAXVAL).all(axis=-1)


class NativeSimulator:
    """Host-side batched simulator for one model; MjData are reused across calls.

    The simulator steps a copy of the model with MuJoCo's automatic reset off: a diverged
    state stays diverged instead of being silently replaced by the initial state (which a
    one-step call from time 0 could not tell apart from a real step). A control step whose
    control or resulting state is non-finite or beyond ``mjMAXVAL`` (MuJoCo would zero such
    a control), and every step after it, is returned as NaN so that callers reject it.

    Calls may come concurrently (one per device when the batch is spread over a mesh,
    :mod:`mjx_surrogate.sharding`): each call takes a free set of MjData (making a new set
    only when all are in use), so concurrent calls run in parallel on their own data."""

    min_batch_per_thread = 32
    # A line search splits its step sizes over threads only where one control step of
    # physics takes longer than this: below, the Python work per step dominates and the
    # threads contend for the GIL. On 2 cores (8 step sizes) threads gained 1.2-1.5x on the
    # fish (16-26 us per control step) and the 15-link swimmer (9-10 us), and lost 1.7-2.5x
    # on the swimmer6 (3-5 us) and the native cartpole (5-7 us). Only speed depends on it.
    min_threaded_step_s = 8e-6

    def __init__(self, mj_model: mujoco.MjModel, substeps: int, nthread: int | None = None):
        self.model = copy.copy(mj_model)
        self.model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_AUTORESET
        self.substeps = substeps
        self.nthread = max(1, nthread or os.cpu_count() or 1)
        self._free: queue.SimpleQueue = queue.SimpleQueue()
        self._free.put(self._new_datas())
        self.nx = mj_model.nq + mj_model.nv + mj_model.na
        data = mujoco.MjData(self.model)
        self.template = np.empty(mujoco.mj_stateSize(self.model, _SPEC))
        mujoco.mj_getState(self.model, data, self.template, _SPEC)

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
        # Small batches run on this thread; large ones on a thread pool made for the call.
        # A persistent pool driven from XLA's callback threads hung the process once in
        # thousands of calls here.
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
        with np.errstate(invalid="ignore"):
            bad = np.logical_or.accumulate(_diverged(ub) | _diverged(X[:, 1:]), axis=1)  # [B, T]
        X[:, 1:][bad] = np.nan
        return X.reshape(lead + (T + 1, self.nx)).astype(x0.dtype, copy=False)

    @functools.cached_property
    def control_step_s(self) -> float:
        """Seconds one control step takes on this thread: the fastest of 5 timings of 5
        steps after a warm-up step, measured once (a single cold timing was noisy enough to
        flip the line search's threading choice)."""
        data = mujoco.MjData(self.model)
        mujoco.mj_step(self.model, data, self.substeps)
        best = np.inf
        for _ in range(5):
            t = time.perf_counter()
            mujoco.mj_step(self.model, data, 5 * self.substeps)
            best = min(best, (time.perf_counter() - t) / 5)
        return best

    def closed_loop(self, x0, X_bar, U_bar, k, K, alphas, lo, hi):
        """u_t = clip(U_bar_t + alpha k_t + K_t (x_t - X_bar_t)) for every alpha at once:
        x0 [nx], X_bar [T+1, nx], U_bar, k [T, nu], K [T, nu, nx], alphas [A]
        -> X [A, T+1, nx], U [A, T, nu].

        One ``mujoco.rollout`` call per control step for a group of step sizes, each
        control step from the full-physics template holding x_t (the numbers of
        :meth:`__call__`). Where a control step's physics outweighs the Python work around
        it, the step sizes are split into one group per thread, each running its whole
        horizon on its own MjData (the GIL is released during the physics)."""
        dtype = np.asarray(x0).dtype
        x0, X_bar, U_bar, k, K, alphas, lo, hi = (
            np.asarray(a, np.float64) for a in (x0, X_bar, U_bar, k, K, alphas, lo, hi)
        )
        T, nu = U_bar.shape
        A = len(alphas)
        X = np.empty((A, T + 1, self.nx))
        U = np.empty((A, T, nu))
        X[:, 0] = x0
        threads = min(self.nthread, A) if self.control_step_s > self.min_threaded_step_s else 1
        groups = np.array_split(np.arange(A), threads)
        try:
            datas = self._free.get_nowait()
        except queue.Empty:
            datas = self._new_datas()
        args = (X, U, X_bar, U_bar, k, K, alphas, lo, hi)
        try:
            with ThreadPoolExecutor(threads - 1) if threads > 1 else nullcontext() as pool:
                jobs = [pool.submit(self._feedback_group, d, g, *args) for d, g in zip(datas[1:], groups[1:])]
                self._feedback_group(datas[0], groups[0], *args)
                for job in jobs:
                    job.result()
        finally:
            self._free.put(datas)
        with np.errstate(invalid="ignore"):
            bad = np.logical_or.accumulate(_diverged(U) | _diverged(X[:, 1:]), axis=1)  # [A, T]
        X[:, 1:][bad] = np.nan
        with np.errstate(over="ignore"):  # a blown-up trial becomes inf: rejected as such
            return X.astype(dtype, copy=False), U.astype(dtype, copy=False)

    def _feedback_group(self, data, idx, X, U, X_bar, U_bar, k, K, alphas, lo, hi) -> None:
        """Fill X[idx], U[idx] of :meth:`closed_loop` on one MjData."""
        g, (T, nu), nx, S = len(idx), U_bar.shape, self.nx, self.substeps
        V = U_bar + alphas[idx, None, None] * k  # [g, T, nu]
        KT = np.swapaxes(K, 1, 2)  # [T, nx, nu]
        Xg, Ug = X[idx], np.empty((g, T, nu))
        init = np.tile(self.template, (g, 1))
        ctrl = np.empty((g, S, nu))
        state = np.empty((g, S, init.shape[1]))
        models = [self.model] * g
        clip = bool(np.isfinite(lo).any() or np.isfinite(hi).any())
        with np.errstate(invalid="ignore", over="ignore"), mj_rollout.Rollout(nthread=0) as pool:
            for t in range(T):
                u = Ug[:, t]
                np.matmul(Xg[:, t] - X_bar[t], KT[t], out=u)
                u += V[:, t]
                if clip:
                    np.clip(u, lo, hi, out=u)
                init[:, 1 : 1 + nx] = Xg[:, t]
                ctrl[:] = u[:, None]
                pool.rollout(models, [data], init, ctrl, skip_checks=True, nstep=S, state=state)
                Xg[:, t + 1] = state[:, -1, 1 : 1 + nx]
        X[idx], U[idx] = Xg, Ug


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
