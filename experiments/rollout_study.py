"""Experiment kind "rollout": perturbed rollouts around the zero-control nominal,
replayed on native MuJoCo as an independent check."""

from __future__ import annotations

import time

import jax
import jax.numpy as jnp
import numpy as np

from mjx_surrogate.identification.rollout import perturbed_rollouts, rollout
from mjx_surrogate.runs import plots
from mjx_surrogate.runs.resolution import Resolved
from mjx_surrogate.runs.results import Run
from mjx_surrogate.tasks import trajectory_cost


def run(res: Resolved, record: Run, key: jax.Array) -> str:
    cfg, system, task = res
    ex = cfg.experiment
    U = jnp.zeros((task.T, system.nu), task.x0.dtype)

    def rollouts():
        t0 = time.perf_counter()
        X_nom = rollout(system, task.x0[None], U[None])[0].block_until_ready()
        out = jax.block_until_ready(
            perturbed_rollouts(system, key, task.x0, U, ex.n_rollouts, ex.rollout_sigma_x, ex.rollout_sigma_u)
        )
        first = time.perf_counter() - t0
        t0 = time.perf_counter()
        jax.block_until_ready(
            perturbed_rollouts(system, key, task.x0, U, ex.n_rollouts, ex.rollout_sigma_x, ex.rollout_sigma_u)
        )
        run_s = time.perf_counter() - t0
        cost = jax.jit(jax.vmap(trajectory_cost, in_axes=(None, 0, 0)))
        costs = np.asarray(cost(task, out.X, U[None] + out.dU))
        # Independent check: replay every perturbed control sequence on native MuJoCo.
        X_native = (
            system.native(np.asarray(task.x0[None] + out.dx0), np.asarray(U[None] + out.dU))
            if system.mj_model is not None
            else None  # a function black box: no MuJoCo to replay on
        )
        finite = np.isfinite(costs)
        m = {
            "nominal": {"cost": float(trajectory_cost(task, X_nom, U))},
            "perturbed": {
                "cost_mean": float(np.mean(costs[finite])) if finite.any() else None,
                "cost_std": float(np.std(costs[finite])) if finite.any() else None,
                "n_rollouts": ex.n_rollouts,
                "n_diverged": int((~finite).sum()),
            },
            "timing": {
                "compile_and_first_run_s": first,
                "run_s": run_s,
                "control_steps_per_s": ex.n_rollouts * task.T / run_s,
            },
            "native_replay_max_abs_diff": None
            if X_native is None
            else _max_diff(X_native, np.asarray(out.X)),
        }
        arrays = {
            "x0": task.x0,
            "nominal_U": U,
            "nominal_X": X_nom,
            "perturbed_dx0": out.dx0,
            "perturbed_dU": out.dU,
            "perturbed_X": out.X,
        }
        return m, arrays

    m, arrays = record.stage("rollouts", rollouts)
    t = np.arange(task.T + 1) * system.dt
    record.figure(
        "rollouts.png",
        lambda: plots.state_fan(
            t,
            arrays["perturbed_X"],
            arrays["nominal_X"],
            list(system.state_labels),
            title=f"{system.name}: {ex.n_rollouts} perturbed rollouts",
        ),
    )
    nominal_ok = np.isfinite(m["nominal"]["cost"])
    # "diverged" when the nominal or every perturbed rollout left the finite states
    return "completed" if nominal_ok and m["perturbed"]["n_diverged"] < ex.n_rollouts else "diverged"


def _max_diff(a: np.ndarray, b: np.ndarray) -> float | None:
    """Largest |a - b| over entries finite in both (None if there is none)."""
    both = np.isfinite(a) & np.isfinite(b)
    return float(np.max(np.abs(a - b)[both])) if both.any() else None
