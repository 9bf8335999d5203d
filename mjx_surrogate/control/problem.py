"""What the iLQR solver sees of one problem: functions and fixed data (:class:`Problem`).

* ``step(x[nx], u[nu]) -> x_next[nx]``: the (black-box) dynamics, used by the forward pass;
* ``linearize(X[T+1, nx], U[T, nu], K[T, nu, nx], key) -> (A[T, nx, nx], B[T, nx, nu])``:
  the local LTV model of the nominal (exact Jacobians, LTV least squares, a surrogate...);
  or, with ``model_rank`` r, a reduced model (A[T, r, r], B[T, r, nu], V[T+1, nx, r]) in
  the coordinates alpha_t = V_t' (x_t - x_bar_t)
  (:mod:`mjx_surrogate.identification.sysid_reduced`);
* ``cost``: :class:`~mjx_surrogate.cost.Cost`, running ``l(x, u)`` and terminal ``l_f(x)``.
"""

from __future__ import annotations

from typing import Any, Callable, NamedTuple

import jax

from mjx_surrogate.cost import Cost

StepFn = Callable[[jax.Array, jax.Array], jax.Array]
LinearizeFn = Callable[[jax.Array, jax.Array, jax.Array, jax.Array], tuple[jax.Array, ...]]
# (x0, X_bar, U_bar, k, K, alphas [A], lo, hi) -> (X [A, T+1, nx], U [A, T, nu])
ClosedLoopFn = Callable[..., tuple[jax.Array, jax.Array]]


class Problem(NamedTuple):
    """The functions (module docstring) and fixed data of one problem: x0 [nx]; u_min, u_max
    [nu]. ``trial_rollouts`` replaces the default line-search forward pass (``step`` rolled
    out in closed loop, vmapped over the step sizes) with one call for all step sizes: the
    native backend makes one host call per iteration with it instead of one per time step.
    ``linearize_fine``: the every-step model a coarse one hands over to. ``model_rank``:
    None for a full-order model, r for a reduced one. ``strategy``: the
    :class:`~mjx_surrogate.control.model_strategies.ModelStrategy` that decides when the
    model is identified (None: the default chain built from the solver's parameters)."""

    step: StepFn
    linearize: LinearizeFn
    cost: Cost
    x0: jax.Array
    u_min: jax.Array
    u_max: jax.Array
    trial_rollouts: ClosedLoopFn | None = None
    linearize_fine: LinearizeFn | None = None
    model_rank: int | None = None
    strategy: Any = None
