"""The iLQR loop's local model of its nominal, and how one is made.

The model: (A [T, r, r], B [T, r, nu]) in the basis V [T+1, nx, r] of a reduced model; V is
empty (shape (0,)) for a full-order one (r = nx); with the nominal it belongs to and the
cost's derivatives there (:class:`LocalModel`). :func:`make_model` carries out a strategy's
:class:`~mjx_surrogate.control.model_strategies.Proposal`: identify (``linearize`` or
``linearize_fine``), carry over by a secant update, or keep. Everything about the model
that the loop carries, the strategies' states included, is a :class:`ModelState`; the
solver's own state (:class:`~mjx_surrogate.control.ilqr.ILQRState`) holds none of it.
"""

from __future__ import annotations

import enum
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp

from mjx_surrogate.control.model_strategies import ModelStrategy, Proposal
from mjx_surrogate.control.problem import Problem
from mjx_surrogate.control.riccati import cost_derivatives, zero_cost_derivatives
from mjx_surrogate.cost import Cost, stage_inputs


class How(enum.IntEnum):
    """How an iteration's model was made (``ILQRResult.identified``)."""

    KEPT = 0  # carried over by a secant update, or kept after a rejected step
    IDENTIFIED = 1  # by ``linearize``
    IDENTIFIED_FINE = 2  # by ``linearize_fine``


class LocalModel(NamedTuple):
    """The model (A, B, V), the nominal it belongs to (X [T+1, nx], U [T, nu]) and the
    cost's derivatives there in the model's coordinates (``expansion``, :func:`model_expansion`)."""

    A: jax.Array
    B: jax.Array
    V: jax.Array
    X: jax.Array
    U: jax.Array
    expansion: tuple


class ModelState(NamedTuple):
    """What the loop carries for its model: the model, the strategies' states, the key of
    the identification's random draws, how each iteration's model was made
    (``identified`` [max_iter] int8, :class:`How`)."""

    model: LocalModel
    strategy: Any
    key: jax.Array
    identified: jax.Array


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


def projected_cost_derivatives(cost: Cost, X: jax.Array, U: jax.Array, V: jax.Array) -> tuple:
    """:func:`reduced_expansion` of the cost's derivatives at X [T+1, nx], U [T, nu] in the
    basis V [T+1, nx, r], built without any nx x nx array: V_t' l_xx V_t and l_ux V_t from
    Hessian-vector products along V_t's r columns (r + nu gradient evaluations a stage, one
    stage at a time), so that a grid of many cells fits. A cost with its own ``derivatives``
    is projected from their dense form."""
    if cost.derivatives is not None:
        return reduced_expansion(cost.derivatives(X, U), V)
    grad = jax.grad(cost.running, argnums=(0, 1))

    def stage(args):
        W, x, u, *t = args  # W [nx, r]
        g = lambda x, u: grad(x, u, *t)  # noqa: E731
        (gx, gu), hvp = jax.linearize(lambda x: g(x, u), x)
        HW, HuW = jax.vmap(hvp, in_axes=1, out_axes=-1)(W)  # l_xx W [nx, r], l_ux W [nu, r]
        luu = jax.jacfwd(lambda u: g(x, u)[1])(u)
        return W.T @ gx, gu, W.T @ HW, luu, HuW

    lx, lu, lxx, luu, lux = jax.lax.map(stage, (V[:-1], *stage_inputs(cost, X, U)))
    gT, hvpT = jax.linearize(jax.grad(cost.terminal), X[-1])
    WT = V[-1]
    return lx, lu, lxx, luu, lux, WT.T @ gT, WT.T @ jax.vmap(hvpT, in_axes=1, out_axes=-1)(WT)


def model_expansion(cost: Cost, X: jax.Array, U: jax.Array, V: jax.Array) -> tuple:
    """The cost's derivatives at X [T+1, nx], U [T, nu] in the coordinates of a model with
    basis V: :func:`~mjx_surrogate.control.riccati.cost_derivatives` for a full-order model
    (V empty), :func:`projected_cost_derivatives` for a reduced one."""
    return cost_derivatives(cost, X, U) if V.size == 0 else projected_cost_derivatives(cost, X, U, V)


def zero_expansion(cost: Cost, X: jax.Array, U: jax.Array, r: int | None) -> tuple:
    """Zeros in the shapes and dtypes of :func:`model_expansion` (r None: full order;
    else the reduced coordinates' [T, r], [T, r, r], ... with no nx x nx array)."""
    if r is None:
        return zero_cost_derivatives(cost, X, U)
    (T, nu), x, u = U.shape, X.dtype, U.dtype
    shapes = (
        ((T, r), x),
        ((T, nu), u),
        ((T, r, r), x),
        ((T, nu, nu), u),
        ((T, nu, r), u),
        ((r,), x),
        ((r, r), x),
    )
    return tuple(jnp.zeros(shape, dtype) for shape, dtype in shapes)


def full_gains(K: jax.Array, V: jax.Array) -> jax.Array:
    """Gains K [T, nu, r] on the model's coordinates as gains on the state: K_t V_t'."""
    return K if V.size == 0 else jnp.einsum("tkr,tnr->tkn", K, V[:-1])


def model_finite(model: LocalModel) -> jax.Array:
    """Whether the model's A and B are finite (a black box that returned NaN or inf in the
    identification's rollouts gives a model that is not)."""
    return jnp.all(jnp.isfinite(model.A)) & jnp.all(jnp.isfinite(model.B))


def init_model(
    problem: Problem, strategy: ModelStrategy, X: jax.Array, U: jax.Array, key: jax.Array, max_iter: int
) -> ModelState:
    """No model yet (zeros) for the first nominal X [T+1, nx], U [T, nu]; the strategies'
    initial states."""
    T, nu = U.shape
    nx, dtype = X.shape[-1], X.dtype
    rank = problem.model_rank
    r = nx if rank is None else rank
    model = LocalModel(
        A=jnp.zeros((T, r, r), dtype),
        B=jnp.zeros((T, r, nu), dtype),
        V=jnp.zeros((0,) if rank is None else (T + 1, nx, r), dtype),
        X=X,
        U=U,
        expansion=zero_expansion(problem.cost, X, U, rank),
    )
    return ModelState(model, strategy.init(), key, jnp.zeros((max_iter,), jnp.int8))


def make_model(
    problem: Problem,
    m: LocalModel,
    proposal: Proposal,
    X: jax.Array,
    U: jax.Array,
    K: jax.Array,
    key: jax.Array,
) -> tuple[LocalModel, jax.Array]:
    """The model of the nominal X [T+1, nx], U [T, nu] (gains K [T, nu, nx] for the schemes
    that use them) as ``proposal`` says, with the cost's derivatives there in its
    coordinates (:func:`model_expansion`), and how it was made (int8 :class:`How`)."""

    def with_basis(model):  # (A, B) of a full-order model, (A, B, V) of a reduced one
        return tuple(model) if problem.model_rank is not None else (*model, m.V)

    def identified():
        coarse = lambda: with_basis(problem.linearize(X, U, K, key))  # noqa: E731
        if problem.linearize_fine is None:
            return coarse()
        return jax.lax.cond(proposal.fine, lambda: with_basis(problem.linearize_fine(X, U, K, key)), coarse)

    def carried():
        dX = model_coordinates(m.V, X - m.X)
        return (*secant_update(m.A, m.B, dX, U - m.U), m.V)

    A, B, V = jax.lax.cond(
        proposal.identify,
        identified,
        lambda: jax.lax.cond(proposal.carry, carried, lambda: (m.A, m.B, m.V)),
    )
    fine = proposal.fine & (problem.linearize_fine is not None)
    how = jnp.where(proposal.identify, jnp.where(fine, How.IDENTIFIED_FINE, How.IDENTIFIED), How.KEPT)
    return LocalModel(A, B, V, X, U, model_expansion(problem.cost, X, U, V)), how.astype(jnp.int8)
