"""The black-box effort of a D2C solve: control steps simulated up to each iteration.

Machine-independent: the initial rollout, the line search's rollouts and every
identification the solver made (``ILQRResult.identified``, coded by
:class:`mjx_surrogate.control.local_model.How`).
"""

from __future__ import annotations

import numpy as np

from mjx_surrogate.control.ilqr import ILQRResult
from mjx_surrogate.control.local_model import How
from mjx_surrogate.identification import sysid as sid


def simulation_curve(
    identified: np.ndarray,
    iterations: int,
    T: int,
    n_alphas: int,
    per_identification: int,
    per_fine_identification: int | None = None,
) -> np.ndarray:
    """Black-box control steps simulated up to each iteration, [iterations + 1]: the
    initial rollout, then per iteration the line search (n_alphas T) and an identification
    where the solver made one (``ILQRResult.identified`` [max_iter]: 1 ``linearize``,
    ``per_identification`` steps; 2 ``linearize_fine``, ``per_fine_identification``)."""
    it = int(iterations)
    ident = np.asarray(identified)[:it]
    fine = per_identification if per_fine_identification is None else per_fine_identification
    coarse = np.where(ident == How.IDENTIFIED, per_identification, 0)
    per = np.where(ident == How.IDENTIFIED_FINE, fine, coarse)
    return T + np.concatenate([[0], np.cumsum(n_alphas * T + per)])


def multistart_steps(
    iterations: np.ndarray,
    identified: np.ndarray,
    T: int,
    n_alphas: int,
    per_id,
    fine: bool,
    lockstep: bool,
) -> int:
    """Black-box control steps of a multi-start solve, all its starts together
    (``MultiStart.iterations`` [S] and ``.identified`` [S, max_iter]; ``per_id``: the pair
    of :func:`steps_per_identification`; ``fine``: a coarse-then-fine scheme). One start
    after another (``lockstep`` False, :func:`mjx_surrogate.control.d2c.in_lockstep`): each
    its own :func:`simulation_curve`. In lockstep (``vmap``) each start simulates every
    iteration until the last start stops, and the strategies' ``lax.cond`` runs both
    branches, so every iteration identifies (both models with a coarse-then-fine scheme).
    The first is checked against a host black box's own call count
    (``tests/test_pipeline.py``)."""
    if not lockstep:
        pairs = zip(identified, iterations)
        return int(sum(simulation_curve(ident, it, T, n_alphas, *per_id)[-1] for ident, it in pairs))
    S, it = len(iterations), int(np.max(iterations))
    per_iteration = n_alphas * T + per_id[0] + (per_id[1] if fine else 0)
    return int(S * (T + it * per_iteration))


def steps_per_identification(sysid: sid.SysIdParams, T: int, nu: int = 0) -> tuple[int, int]:
    """Control steps of one identification of the D2C solve's coarse and fine models
    (equal unless ``sysid.every`` > 1: then every k-th step first, every step near the end);
    nu: the controls (a reduced scheme's one-step samples count them)."""
    fine = sid.fine_params(sysid) or sysid
    return sid.steps_per_identification(sysid, T, nu), sid.steps_per_identification(fine, T, nu)


def simulation_metrics(result: ILQRResult, T: int, n_alphas: int, sysid: sid.SysIdParams) -> dict:
    """``simulated_steps`` of a D2C solve and ``simulations_to_optimum``: the control steps
    simulated until the cost first came within 1 % and 0.1 % of the solve's final cost
    (machine-independent effort; None if the final cost is not finite)."""
    curve = simulation_curve(
        result.identified,
        result.iterations,
        T,
        n_alphas,
        *steps_per_identification(sysid, T, result.U.shape[-1]),
    )
    J = np.asarray(result.cost_history)[: curve.size]
    to = {}
    for label, rel in (("1%", 1e-2), ("0.1%", 1e-3)):
        hit = np.nonzero(J <= J[-1] + rel * abs(J[-1]))[0] if np.isfinite(J[-1]) else []
        to[label] = int(curve[hit[0]]) if len(hit) else None
    return {"simulated_steps": int(curve[-1]), "simulations_to_optimum": to}
