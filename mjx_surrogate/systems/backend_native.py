"""Native backend: MuJoCo C through ``mujoco.rollout``, called from jitted code.

The host call sits behind ``jax.pure_callback`` so a surrounding ``jit``/``vmap``/
``while_loop`` trace is unchanged; it is a true black box (no derivatives) and runs
every MuJoCo feature. Whole horizons go to C in one call, multi-threaded.

MuJoCo silently zeroes non-finite controls and resets a diverged state (``mj_resetData``,
which also resets ``time``); both are mapped to NaN states here so callers can reject them.
"""

from __future__ import annotations

import os
import threading

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

_SPEC = mujoco.mjtState.mjSTATE_FULLPHYSICS

# MuJoCo prints a warning for every diverged trial (line searches provoke many); they
# are counted here instead, and surfaced as NaN states to the caller.
WARNINGS = {"count": 0, "last": ""}


def _count_warning(msg: str) -> None:
    WARNINGS["count"] += 1
    WARNINGS["last"] = msg


mujoco.set_mju_user_warning(_count_warning)


class NativeSimulator:
    """Host-side batched simulator for one model; thread pool and MjData are reused."""

    def __init__(self, mj_model: mujoco.MjModel, substeps: int, nthread: int | None = None):
        self.model = mj_model
        self.substeps = substeps
        self.nthread = max(1, nthread or os.cpu_count() or 1)
        self.datas = [mujoco.MjData(mj_model) for _ in range(self.nthread)]
        self.nx = mj_model.nq + mj_model.nv + mj_model.na
        data = mujoco.MjData(mj_model)
        self.template = np.empty(mujoco.mj_stateSize(mj_model, _SPEC))
        mujoco.mj_getState(mj_model, data, self.template, _SPEC)
        self._lock = threading.Lock()
        self._runner = mj_rollout.Rollout(nthread=self.nthread) if self.nthread > 1 else None

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
        with self._lock:
            if self._runner is not None:
                state, _ = self._runner.rollout(self.model, self.datas, init, ctrl)
            else:
                state, _ = mj_rollout.rollout(self.model, self.datas[0], init, ctrl)
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

    def close(self) -> None:
        if self._runner is not None:
            self._runner.close()
            self._runner = None


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
