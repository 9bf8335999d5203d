"""Replay of a run's controls on native MuJoCo in float64, open and closed loop.

The reference a reader can rebuild from a run folder alone (``model.mjb``, ``x0``,
``NAME_U``, ``NAME_X``, ``NAME_K``): one ``mujoco.mj_step`` call per physics step, no JAX,
no MJX. The state is x = [qpos, qvel, act]; a control step is ``substeps`` physics steps.

* open loop: u_t = clip(U_t);
* closed loop: u_t = clip(U_t + K_t (x_t - X_t)) around the stored nominal X [T+1, nx].

An optimum that is unstable open loop (a swing-up near the top, a juggling cart-pole)
amplifies any difference of arithmetic or backend from the solver's own, so it can only be
replayed to its cost with the feedback it was computed with; a stable one replays either
way. Runs report both and judge by the closed loop (``JUDGED_BY``).
"""

from __future__ import annotations

import mujoco
import numpy as np

JUDGED_BY = "closed_loop"


def replay(
    model: mujoco.MjModel,
    substeps: int,
    x0: np.ndarray,
    U: np.ndarray,
    X: np.ndarray | None = None,
    K: np.ndarray | None = None,
    u_min: np.ndarray | None = None,
    u_max: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Controls U [T, nu] from x0 [nx] on native MuJoCo, float64; closed loop when X
    [T+1, nx] and K [T, nu, nx] are given. Returns (states [T+1, nx], applied controls
    [T, nu]); a state MuJoCo cannot continue from ends the replay with NaN."""
    nq, nv = model.nq, model.nv
    U = np.asarray(U, np.float64)
    T, nu = U.shape
    lo = np.full(nu, -np.inf) if u_min is None else np.asarray(u_min, np.float64)
    hi = np.full(nu, np.inf) if u_max is None else np.asarray(u_max, np.float64)
    closed = X is not None and K is not None
    if closed:
        X, K = np.asarray(X, np.float64), np.asarray(K, np.float64)
    data = mujoco.MjData(model)
    x = np.asarray(x0, np.float64).copy()
    data.qpos[:], data.qvel[:], data.act[:] = x[:nq], x[nq : nq + nv], x[nq + nv :]
    states = np.full((T + 1, x.size), np.nan)
    states[0] = x
    applied = np.full((T, nu), np.nan)
    for t in range(T):
        u = U[t] + K[t] @ (x - X[t]) if closed else U[t]
        applied[t] = np.clip(u, lo, hi)
        data.ctrl[:] = applied[t]
        for _ in range(substeps):
            mujoco.mj_step(model, data)
        x = np.concatenate([data.qpos, data.qvel, data.act])
        if not np.all(np.isfinite(x)):
            break
        states[t + 1] = x
    return states, applied


def replay_costs(cost_fn, model, substeps, x0, U, X, K, u_min, u_max) -> dict:
    """Open- and closed-loop native float64 costs of one run's controls, by ``cost_fn(X,
    U) -> J`` (the task's cost; +inf or None for a trajectory that is not finite)."""
    out = {}
    for mode, (Xn, Kn) in (("open_loop", (None, None)), ("closed_loop", (X, K))):
        states, applied = replay(model, substeps, x0, U, Xn, Kn, u_min, u_max)
        out[mode] = cost_fn(states, applied)
    out["judged_by"] = JUDGED_BY
    return out
