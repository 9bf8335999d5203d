"""Optimal control on a surrogate model, judged on the black box (paper, Fig. "control").

The iLQR of :mod:`mjx_surrogate.ilqr` runs on the surrogate's step with Jacobians by
``jax.jacfwd`` through it; its controls U and gains K are then executed on the black box
open loop (u_t = U_t) and closed loop (u_t = U_t + K_t (x_t - X_t), X the surrogate's
predicted nominal). What counts is the true cost on the black box.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from mjx_surrogate import sysid
from mjx_surrogate.d2c import task_cost
from mjx_surrogate.ilqr import ILQRParams, ILQRResult, closed_loop, ilqr
from mjx_surrogate.systems.system import System
from mjx_surrogate.tasks import Task, trajectory_cost


class TrueOutcome(NamedTuple):
    cost_open: jax.Array  # true cost of U on the black box
    cost_closed: jax.Array  # true cost with the surrogate's feedback gains
    X_open: jax.Array  # [T+1, nx] black-box trajectories
    X_closed: jax.Array
    final_error_open: jax.Array  # |x_T - x_goal|
    final_error_closed: jax.Array


@jax.jit
def solve_on_model(model, task: Task, U0: jax.Array, params: ILQRParams) -> ILQRResult:
    """iLQR on a differentiable surrogate (a pytree with ``step(x, u)``, e.g. a SindyModel
    or MLPModel) from U0 [T, nu]."""
    step = model.step
    lin = lambda X, U, K, key: sysid.exact_jacobians(step, X, U)  # noqa: E731
    return ilqr(step, lin, task_cost(task), task.x0, U0, task.u_min, task.u_max, params,
                jax.random.key(0))


def on_black_box(system: System, task: Task, sol: ILQRResult) -> TrueOutcome:
    """Execute a solution's controls on the black box, open and closed loop."""
    zeros_k = jnp.zeros_like(sol.U)
    Xo, Uo = closed_loop(system.step, task.x0, sol.X, sol.U, zeros_k, jnp.zeros_like(sol.K),
                         jnp.zeros(()), task.u_min, task.u_max)
    Xc, Uc = closed_loop(system.step, task.x0, sol.X, sol.U, zeros_k, sol.K, jnp.zeros(()),
                         task.u_min, task.u_max)
    err = lambda X: jnp.linalg.norm(X[-1] - task.x_goal)  # noqa: E731
    return TrueOutcome(trajectory_cost(task, Xo, Uo), trajectory_cost(task, Xc, Uc), Xo, Xc,
                       err(Xo), err(Xc))
