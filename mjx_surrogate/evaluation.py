"""Prediction error of a model against the black box on held-out trajectories."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from mjx_surrogate import models
from mjx_surrogate.data import Dataset


def prediction_errors(step_t: models.StepT, test: Dataset) -> tuple[dict, np.ndarray]:
    """One-step and open-loop multi-step RMSE of ``step_t`` on test trajectories.

    Returns (metrics, X_pred [N, T+1, nx]). metrics: one_step_rmse and multi_step_rmse
    over all test transitions/steps, multi_step_median (median over trajectories of each
    trajectory's RMSE) and diverged (fraction of trajectories whose prediction went
    non-finite). RMSEs that are not finite are reported as None.
    """
    ok = np.asarray(jnp.isfinite(test.X).all((1, 2)))
    X, U = test.X[ok], test.U[ok]
    pred = jax.jit(lambda x0, u: models.predict(step_t, x0, u))(X[:, 0], U)
    one = jax.jit(lambda x, u: models.one_step(step_t, x, u))(X, U)
    err_multi = np.asarray((pred - X) ** 2)
    per_traj = np.sqrt(err_multi.reshape(err_multi.shape[0], -1).mean(1))
    finite = np.isfinite(per_traj)

    def num(v):
        v = float(v)
        return v if np.isfinite(v) else None

    out = {
        "one_step_rmse": num(models.rmse(one, X[:, 1:])),
        "multi_step_rmse": num(np.sqrt(err_multi.mean())) if finite.all() else None,
        "multi_step_median": num(np.median(np.where(finite, per_traj, np.inf))),
        "diverged": float(1.0 - finite.mean()),
    }
    return out, np.asarray(pred)
