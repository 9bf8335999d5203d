"""Step models: one interface for every model of the dynamics, a jittable time-indexed map

    step(t, x [nx], u [nu]) -> x_next [nx]

for the exact black box, the local LTV model, SINDy and MLP surrogates. Time-invariant
maps ignore t. ``predict`` rolls any of them out open loop (a ``lax.scan`` over t, vmapped
over the batch); ``one_step`` evaluates them on given (x_t, u_t). A surrogate's own
time-invariant ``step(x, u)`` is what the iLQR takes (``surrogate_control``).

A fitted model passed as a :class:`jax.tree_util.Partial` (:func:`as_pytree`) is an
argument of a jitted function rather than a constant of it: one program serves every fit
of the same structure and shapes (every perturbation level, every seed).
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from mjx_surrogate.identification import sysid
from mjx_surrogate.identification.data import Dataset, finite_trajectories
from mjx_surrogate.systems.black_box import BlackBox
from mjx_surrogate.trajectory import simulate_t

StepT = Callable[[jax.Array, jax.Array, jax.Array], jax.Array]


class LTVModel(NamedTuple):
    """x_{t+1} = X_{t+1} + A_t (x - X_t) + B_t (u - U_t) around a nominal (X, U)."""

    X: jax.Array  # [T+1, nx]
    U: jax.Array  # [T, nu]
    A: jax.Array  # [T, nx, nx]
    B: jax.Array  # [T, nx, nu]

    def step_t(self, t: jax.Array, x: jax.Array, u: jax.Array) -> jax.Array:
        return self.X[t + 1] + self.A[t] @ (x - self.X[t]) + self.B[t] @ (u - self.U[t])

    def as_pytree(self) -> jax.tree_util.Partial:
        """``step_t`` with this model's arrays as the leaves of a pytree."""
        return jax.tree_util.Partial(LTVModel.step_t, self)


def fit_ltv(data: Dataset, X_nom: jax.Array, U_nom: jax.Array) -> LTVModel:
    """The paper's local model from a data set: for each t, least squares of
    x_{t+1} - X_{t+1} on [x_t - X_t, u_t - U_t] over the data set's trajectories."""
    dX, dU = _finite_deviations(data, X_nom, U_nom)
    A, B = sysid.fit_from_trajectories(dX, dU)
    return LTVModel(X_nom, U_nom, A, B)


def _finite_deviations(data: Dataset, X_nom: jax.Array, U_nom: jax.Array) -> tuple[np.ndarray, np.ndarray]:
    """dX [n, T+1, nx], dU [n, T, nu] of the data set's finite trajectories from the nominal."""
    X, U = finite_trajectories(data)
    return X - np.asarray(X_nom), U - np.asarray(U_nom)


def fit_reduced_ltv(data: Dataset, X_nom: jax.Array, U_nom: jax.Array, rank_tol: float) -> LTVModel:
    """The local model of :func:`fit_ltv` identified in the data's own snapshot basis per t
    (:func:`mjx_surrogate.identification.sysid_reduced.fit_in_snapshot_basis`), returned in full order."""
    from mjx_surrogate.identification import sysid_reduced

    A, B, V = sysid_reduced.fit_in_snapshot_basis(*_finite_deviations(data, X_nom, U_nom), rank_tol)
    return LTVModel(X_nom, U_nom, *sysid_reduced.lift_model(A, B, V))


def time_invariant(step: Callable[[jax.Array, jax.Array], jax.Array]) -> StepT:
    """Lift step(x, u) to the time-indexed interface."""
    return lambda t, x, u: step(x, u)


def _surrogate_step_t(model, t: jax.Array, x: jax.Array, u: jax.Array) -> jax.Array:
    return model.step(x, u)


def as_pytree(model) -> jax.tree_util.Partial:
    """A surrogate's ``step(x, u)`` on the time-indexed interface, as a pytree whose leaves
    are the model's arrays; a model that is not a pytree of arrays stays a constant."""
    leaves = jax.tree_util.tree_leaves(model)
    if leaves and all(isinstance(leaf, (jax.Array, np.ndarray)) for leaf in leaves):
        return jax.tree_util.Partial(_surrogate_step_t, model)
    return jax.tree_util.Partial(time_invariant(model.step))


def black_box(system: BlackBox) -> StepT:
    """The exact model: the system's own step (MJX or native MuJoCo)."""
    return time_invariant(system.step)


def predict(step_t: StepT, x0: jax.Array, U: jax.Array) -> jax.Array:
    """Open-loop multi-step prediction: x0 [B, nx], U [B, T, nu] -> X [B, T+1, nx]."""
    return jax.vmap(simulate_t, in_axes=(None, 0, 0))(step_t, x0, U)


def one_step(step_t: StepT, X: jax.Array, U: jax.Array) -> jax.Array:
    """One-step predictions from the true states: X [B, T+1, nx], U [B, T, nu] -> [B, T, nx]."""
    ts = jnp.arange(U.shape[1])
    per_t = jax.vmap(step_t, in_axes=(0, 0, 0))  # over t
    return jax.vmap(lambda x, u: per_t(ts, x[:-1], u))(X, U)


@jax.jit
def rmse(pred: jax.Array, true: jax.Array) -> jax.Array:
    """Root-mean-square error over everything but the last (state) axis, per coordinate
    averaged: sqrt(mean((pred - true)^2)); non-finite predictions count as +inf."""
    err = (pred - true) ** 2
    return jnp.sqrt(jnp.mean(jnp.where(jnp.isfinite(err), err, jnp.inf)))
