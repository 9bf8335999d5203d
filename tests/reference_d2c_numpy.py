"""Reference D2C in plain NumPy + native ``mujoco.rollout`` (no JAX).

The same algorithm as ``mjx_surrogate.control.d2c.solve_d2c`` with central- or forward-difference
LTV identification: one multi-threaded ``mujoco.rollout`` call identifies all T models; the
line search simulates all step sizes together, one batched call per control step. It is
the same-run speed reference of ``benchmarks/d2c.py`` and an independent numerical
cross-check (tests/test_reference_d2c.py). No control limits (D2C 2.0 used none).
"""

from __future__ import annotations

import mujoco
import numpy as np
from mujoco import rollout as mj_rollout


class NativeStepper:
    """x [N, nx], u [N, nu] -> x_next [N, nx] after ``substeps`` physics steps."""

    def __init__(self, model: mujoco.MjModel, substeps: int, nthread: int = 2):
        self.m, self.S = model, substeps
        self.nx = model.nq + model.nv
        self.spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
        self.template = np.zeros(mujoco.mj_stateSize(model, self.spec))
        mujoco.mj_getState(model, mujoco.MjData(model), self.template, self.spec)
        self.datas = [mujoco.MjData(model) for _ in range(nthread)]
        self.runner = mj_rollout.Rollout(nthread=nthread)

    def __call__(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        init = np.repeat(self.template[None], len(x), 0)
        init[:, 1 : 1 + self.nx] = x
        ctrl = np.repeat(u[:, None], self.S, axis=1)
        state, _ = self.runner.rollout(self.m, self.datas, init, ctrl)
        out = state[:, -1, 1 : 1 + self.nx]
        reset = (np.diff(np.concatenate([init[:, :1], state[:, :, 0]], 1), axis=1) <= 0).any(1)
        out[reset | ~np.isfinite(u).all(1)] = np.nan
        return out


def rollout_closed_loop(step, x0, Xb, Ub, k, K, alphas):
    """All step sizes at once: returns X [A, T+1, nx], U [A, T, nu]."""
    nA, (T, nu) = len(alphas), Ub.shape
    X = np.empty((nA, T + 1, len(x0)))
    U = np.empty((nA, T, nu))
    X[:, 0] = x0
    for t in range(T):
        U[:, t] = Ub[t] + alphas[:, None] * k[t] + (X[:, t] - Xb[t]) @ K[t].T
        X[:, t + 1] = step(X[:, t], U[:, t])
    return X, U


def cost(X, U, xg, Q, Qf, R):
    """J for X [..., T+1, nx], U [..., T, nu]; inf where not finite or blown up."""
    dx = X - xg
    J = 0.5 * (
        np.einsum("...ti,ij,...tj->...", dx[..., :-1, :], Q, dx[..., :-1, :])
        + np.einsum("...ti,ij,...tj->...", U, R, U)
        + np.einsum("...i,ij,...j->...", dx[..., -1, :], Qf, dx[..., -1, :])
    )
    bad = ~np.isfinite(X).all((-1, -2)) | (np.abs(np.nan_to_num(X, nan=np.inf)).max((-1, -2)) > 1e8)
    return np.where(bad | ~np.isfinite(J), np.inf, J)


def identify(step, X, U, rng, n, sigma, scheme="central_difference"):
    """A [T, nx, nx], B [T, nx, nu] from one batched simulation; ``scheme`` is
    "central_difference" (2 n T steps) or "forward_difference" ((n + 1) T steps)."""
    T, nu = U.shape
    nx = X.shape[1]
    dx = sigma * rng.standard_normal((T, n, nx))
    du = sigma * rng.standard_normal((T, n, nu))
    if scheme == "forward_difference":
        xs = np.concatenate([X[:-1, None], X[:-1, None] + dx], 1).reshape(-1, nx)
        us = np.concatenate([U[:, None], U[:, None] + du], 1).reshape(-1, nu)
        f = step(xs, us).reshape(T, n + 1, nx)
        Y = f[:, 1:] - f[:, :1]
    else:
        xs = np.concatenate([X[:-1, None] + dx, X[:-1, None] - dx], 1).reshape(-1, nx)
        us = np.concatenate([U[:, None] + du, U[:, None] - du], 1).reshape(-1, nu)
        f = step(xs, us).reshape(T, 2 * n, nx)
        Y = 0.5 * (f[:, :n] - f[:, n:])
    Z = np.concatenate([dx, du], -1)
    W = np.stack([np.linalg.lstsq(Z[t], Y[t], rcond=None)[0] for t in range(T)])
    return np.transpose(W[:, :nx], (0, 2, 1)), np.transpose(W[:, nx:], (0, 2, 1))


def backward(A, B, X, U, xg, Q, Qf, R, mu):
    T, nu = U.shape
    nx = X.shape[1]
    Vx, Vxx = Qf @ (X[-1] - xg), Qf.copy()
    k, K = np.zeros((T, nu)), np.zeros((T, nu, nx))
    dV = np.zeros(2)
    for t in reversed(range(T)):
        At, Bt = A[t], B[t]
        Qx, Qu = Q @ (X[t] - xg) + At.T @ Vx, R @ U[t] + Bt.T @ Vx
        Qxx, Quu = Q + At.T @ Vxx @ At, R + Bt.T @ Vxx @ Bt
        Qux = Bt.T @ Vxx @ At
        Quu_r, Qux_r = Quu + mu * Bt.T @ Bt, Qux + mu * Bt.T @ At  # shape the step only
        try:
            np.linalg.cholesky(Quu_r)
        except np.linalg.LinAlgError:
            return None
        kK = -np.linalg.solve(Quu_r, np.column_stack([Qu, Qux_r]))
        k[t], K[t] = kK[:, 0], kK[:, 1:]
        Vx = Qx + K[t].T @ Quu @ k[t] + K[t].T @ Qu + Qux.T @ k[t]
        Vxx = Qxx + K[t].T @ Quu @ K[t] + K[t].T @ Qux + Qux.T @ K[t]
        Vxx = 0.5 * (Vxx + Vxx.T)
        dV += [k[t] @ Qu, 0.5 * k[t] @ Quu @ k[t]]
    return k, K, dV


def solve(
    step,
    x0,
    U0,
    xg,
    Q,
    Qf,
    R,
    seed=0,
    n_samples=10,
    sigma=1e-3,
    max_iter=100,
    rel_tol=1e-6,
    n_alphas=8,
    mu=1e-6,
    mu_min=1e-8,
    mu_max=1e10,
    factor=4.0,
    accept_ratio=1e-4,
    scheme="central_difference",
):
    """Returns dict(U, X, cost, iterations, history)."""
    rng = np.random.default_rng(seed)
    T, nu = U0.shape
    alphas = 0.5 ** np.arange(n_alphas)
    X, U = rollout_closed_loop(
        step, x0, np.zeros((T + 1, len(x0))), U0, np.zeros((T, nu)), np.zeros((T, nu, len(x0))), np.zeros(1)
    )
    X, U = X[0], U[0]
    J = float(cost(X, U, xg, Q, Qf, R))
    history, fresh, it = [J], True, 0
    while it < max_iter and np.isfinite(J):
        if fresh:
            A, B = identify(step, X, U, rng, n_samples, sigma, scheme)
        it += 1
        bp = backward(A, B, X, U, xg, Q, Qf, R, mu)
        accepted = False
        if bp is not None:
            k, K, dV = bp
            Xa, Ua = rollout_closed_loop(step, x0, X, U, k, K, alphas)
            Ja = cost(Xa, Ua, xg, Q, Qf, R)
            expected = -(alphas * dV[0] + alphas**2 * dV[1])
            ratio = (J - Ja) / np.where(expected > 0, expected, np.inf)
            ok = np.isfinite(Ja) & (Ja < J) & (ratio > accept_ratio)
            if ok.any():
                i = np.argmin(np.where(ok, Ja, np.inf))
                dJ, X, U, J, accepted = J - Ja[i], Xa[i], Ua[i], float(Ja[i]), True
            elif abs(dV.sum()) <= rel_tol * abs(J):
                history.append(J)
                break
        mu = max(mu / factor, mu_min) if accepted else max(mu * factor, mu_min)
        fresh = accepted
        history.append(J)
        if (accepted and dJ <= rel_tol * abs(J)) or mu > mu_max:
            break
    return {"U": U, "X": X, "cost": J, "iterations": it, "history": np.array(history)}
