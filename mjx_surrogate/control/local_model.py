"""The iLQR loop's local model and the strategies that decide when it is identified.

The loop (:mod:`mjx_surrogate.control.ilqr`) asks for a model of its nominal once per iteration
(:func:`model_for`) and reports the outcome of the step it took on it (:func:`after_step`);
everything else about the model lives in :class:`ModelState`, which this module alone
reads and writes. Each strategy has its own typed part of that state:

* **reuse** (:class:`ReuseState`; ``reuse_tol`` > 0 and ``reuse_max`` > 0): when the
  accepted step's decrease was within ``reuse_tol`` of the model's promise, the next
  iteration skips the identification and carries the model over with a secant update
  from the step just taken (:func:`secant_update`), at most ``reuse_max`` iterations in a
  row; a step rejected on a carried-over model is retried on a freshly identified one.
* **coarse then fine** (:class:`RefineState`; ``Problem.linearize_fine`` given):
  iterations identify with ``linearize`` until the coarse model hands over (a stopping
  rule would fire on it, or a step gains at most ``refine_tol`` |J|), then with
  ``linearize_fine``.

A minimum is declared only on a model that is trusted (:func:`trusted`): identified on its
own nominal (not carried over) and fine. Models: (A [T, r, r], B [T, r, nu]) in the basis
V [T+1, nx, r] of a reduced model; V is empty (shape (0,)) for a full-order one (r = nx).
"""

from __future__ import annotations

import enum
from typing import TYPE_CHECKING, NamedTuple

import jax
import jax.numpy as jnp

from mjx_surrogate.control.riccati import zero_cost_derivatives

if TYPE_CHECKING:
    from mjx_surrogate.control.ilqr import Problem


class How(enum.IntEnum):
    """How an iteration's model was made (``ILQRResult.identified``)."""

    KEPT = 0  # carried over by a secant update, or kept after a rejected step
    IDENTIFIED = 1  # by ``linearize``
    IDENTIFIED_FINE = 2  # by ``linearize_fine``


class ReuseState(NamedTuple):
    """Model reuse: the nominal moved since the model was made (``fresh``), the model was
    carried over rather than identified (``stale``), the last accepted step passed the
    reuse test (``ok``), iterations in a row on a carried-over model (``count``)."""

    fresh: jax.Array
    stale: jax.Array
    ok: jax.Array
    count: jax.Array


class RefineState(NamedTuple):
    """Coarse then fine: identify with ``linearize_fine`` from now on (``fine``); the
    current model came from it (``fine_model``). Both True when no fine model is given."""

    fine: jax.Array
    fine_model: jax.Array


class ModelState(NamedTuple):
    """The model (A, B, V), the nominal it belongs to (X [T+1, nx], U [T, nu]), the cost's
    derivatives there (``expansion``, :func:`~mjx_surrogate.control.riccati.cost_derivatives`),
    and the strategies' own states."""

    A: jax.Array
    B: jax.Array
    V: jax.Array
    X: jax.Array
    U: jax.Array
    expansion: tuple
    reuse: ReuseState
    refine: RefineState


class StepOutcome(NamedTuple):
    """What the loop tells the model about the step it took on it: a trial was accepted;
    the accepted trial's actual / predicted decrease; a stopping rule for a minimum held;
    the step gained at most ``refine_tol`` |J|; mu passed mu_max."""

    accepted: jax.Array
    ratio: jax.Array
    at_minimum: jax.Array
    gain_small: jax.Array
    stalled: jax.Array


def secant_update(A: jax.Array, B: jax.Array, dX: jax.Array, dU: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Broyden's rank-one update of each W_t = [A_t B_t] to the nominal's own step:
    W_t += (dx_{t+1} - W_t s_t) s_t' / (s_t' s_t), s_t = [dx_t; du_t], so that W_t s_t =
    dx_{t+1} afterwards and W_t is unchanged on directions orthogonal to s_t. A [T, nx, nx],
    B [T, nx, nu], dX [T+1, nx], dU [T, nu]; a step below round-off leaves W_t as it is."""
    nx = A.shape[-1]
    W = jnp.concatenate([A, B], axis=-1)  # [T, nx, nx+nu]
    S = jnp.concatenate([dX[:-1], dU], axis=-1)  # [T, nx+nu]
    r = dX[1:] - jnp.einsum("tij,tj->ti", W, S)
    ss = jnp.sum(S * S, axis=-1)
    ok = ss > (1e3 * jnp.finfo(A.dtype).eps) ** 2
    W = W + jnp.where(ok, 1.0 / jnp.where(ok, ss, 1.0), 0.0)[:, None, None] * r[:, :, None] * S[:, None, :]
    return W[..., :nx], W[..., nx:]


def model_coordinates(V: jax.Array, dX: jax.Array) -> jax.Array:
    """dX [T+1, nx] in the model's coordinates: V_t' dX_t [T+1, r] (dX itself when V is
    empty: a full-order model)."""
    return dX if V.size == 0 else jnp.einsum("tn,tnr->tr", dX, V)


def reduced_expansion(derivs: tuple, V: jax.Array) -> tuple:
    """The cost's derivatives (:func:`~mjx_surrogate.control.riccati.cost_derivatives`) in
    the coordinates of the basis V [T+1, nx, r]: l_x V_t, V_t' l_xx V_t, l_ux V_t, V_T' V_x,
    V_T' V_xx V_T (unchanged when V is empty)."""
    if V.size == 0:
        return derivs
    lx, lu, lxx, luu, lux, VxT, VxxT = derivs
    W, WT = V[:-1], V[-1]
    lxx_r = jnp.einsum("tnr,tnm,tms->trs", W, lxx, W)
    return (
        jnp.einsum("tn,tnr->tr", lx, W),
        lu,
        lxx_r,
        luu,
        jnp.einsum("tkn,tnr->tkr", lux, W),
        WT.T @ VxT,
        WT.T @ VxxT @ WT,
    )


def full_gains(K: jax.Array, V: jax.Array) -> jax.Array:
    """Gains K [T, nu, r] on the model's coordinates as gains on the state: K_t V_t'."""
    return K if V.size == 0 else jnp.einsum("tkr,tnr->tkn", K, V[:-1])


def init_model(problem: Problem, X: jax.Array, U: jax.Array) -> ModelState:
    """No model yet (zeros), for the first nominal X [T+1, nx], U [T, nu]: the first
    iteration identifies, with ``linearize`` (coarse) where a fine model is given."""
    T, nu = U.shape
    nx, dtype = X.shape[-1], X.dtype
    rank = problem.model_rank
    r = nx if rank is None else rank
    fine = problem.linearize_fine is None
    return ModelState(
        A=jnp.zeros((T, r, r), dtype),
        B=jnp.zeros((T, r, nu), dtype),
        V=jnp.zeros((0,) if rank is None else (T + 1, nx, r), dtype),
        X=X,
        U=U,
        expansion=zero_cost_derivatives(problem.cost, X, U),
        reuse=ReuseState(jnp.array(True), jnp.array(False), jnp.array(False), jnp.asarray(0)),
        refine=RefineState(jnp.array(fine), jnp.array(fine)),
    )


def model_for(
    problem: Problem,
    m: ModelState,
    X: jax.Array,
    U: jax.Array,
    K: jax.Array,
    key: jax.Array,
    expansion: tuple,
) -> tuple[ModelState, jax.Array]:
    """The model of the nominal X [T+1, nx], U [T, nu] (gains K [T, nu, nx] for the schemes
    that use them), with the cost's derivatives there, and how it was made (int8: 0
    carried over or kept, 1 identified by ``linearize``, 2 by ``linearize_fine``: :class:`How`)."""
    reuse, refine = m.reuse, m.refine
    # A new nominal is identified afresh unless the last step passed the reuse test; then
    # the model is carried over with a secant update, and identified afresh as soon as a
    # step is rejected on it. A coarse model that handed over is identified again, fine.
    identify = (reuse.fresh & ~reuse.ok) | (~reuse.fresh & reuse.stale) | (refine.fine & ~refine.fine_model)
    update = reuse.fresh & reuse.ok & ~identify

    def with_basis(model):  # (A, B) of a full-order model, (A, B, V) of a reduced one
        return tuple(model) if problem.model_rank is not None else (*model, m.V)

    def identified():
        coarse = lambda: with_basis(problem.linearize(X, U, K, key))  # noqa: E731
        if problem.linearize_fine is None:
            return coarse()
        return jax.lax.cond(refine.fine, lambda: with_basis(problem.linearize_fine(X, U, K, key)), coarse)

    def carried():
        dX = model_coordinates(m.V, X - m.X)
        return (*secant_update(m.A, m.B, dX, U - m.U), m.V)

    A, B, V = jax.lax.cond(
        identify, identified, lambda: jax.lax.cond(update, carried, lambda: (m.A, m.B, m.V))
    )
    fine_model = jnp.where(identify, refine.fine, refine.fine_model)
    reuse = reuse._replace(
        stale=~identify & (update | reuse.stale), count=jnp.where(identify, 0, reuse.count + update)
    )
    by = jnp.where(fine_model & (problem.linearize_fine is not None), How.IDENTIFIED_FINE, How.IDENTIFIED)
    how = jnp.where(identify, by, How.KEPT).astype(jnp.int8)
    return ModelState(A, B, V, X, U, expansion, reuse, refine._replace(fine_model=fine_model)), how


def trusted(m: ModelState) -> jax.Array:
    """Whether a minimum may be declared on the model: identified on its own nominal (not
    carried over) and fine."""
    return ~m.reuse.stale & m.refine.fine_model


def is_fine(m: ModelState) -> jax.Array:
    """Whether the model is the fine one (a stall is declared on fine models only)."""
    return m.refine.fine_model


def after_step(params, m: ModelState, outcome: StepOutcome) -> tuple[ModelState, jax.Array]:
    """The strategies' states after the loop's step on the model (``params``: the solver's
    ``ILQRParams``); also whether the coarse model handed over to the fine one (the loop
    then restarts its regularisation schedule)."""
    handover = ~m.refine.fine_model & (outcome.at_minimum | outcome.stalled | outcome.gain_small)
    near = jnp.abs(outcome.ratio - 1.0) <= params.reuse_tol
    ok = outcome.accepted & near & (m.reuse.count < params.reuse_max) & ~outcome.at_minimum
    reuse = m.reuse._replace(fresh=outcome.accepted, ok=ok)
    return m._replace(reuse=reuse, refine=m.refine._replace(fine=m.refine.fine | handover)), handover
