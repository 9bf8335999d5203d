"""Optimal control on a surrogate model, judged on the black box (paper, Fig. "control").

The iLQR of :mod:`mjx_surrogate.control.ilqr` runs on the surrogate's step with Jacobians by
``jax.jacfwd`` through it; its controls U and gains K are then executed on the black box
(:func:`mjx_surrogate.analysis.evaluation.replay`) open and closed loop. What counts is the true
cost on the black box.
"""

from __future__ import annotations

import jax

from mjx_surrogate.control.ilqr import ILQRParams, ILQRResult, ilqr
from mjx_surrogate.identification import sysid
from mjx_surrogate.tasks import Task, task_cost


@jax.jit
def solve_on_model(model, task: Task, U0: jax.Array, params: ILQRParams) -> ILQRResult:
    """iLQR on a differentiable surrogate (a pytree with ``step(x, u)``, e.g. a SindyModel
    or MLPModel) from U0 [T, nu]."""
    step = model.step
    lin = lambda X, U, K, key: sysid.exact_jacobians(step, X, U)  # noqa: E731
    return ilqr(step, lin, task_cost(task), task.x0, U0, task.u_min, task.u_max, params, jax.random.key(0))
