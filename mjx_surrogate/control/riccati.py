"""The backward pass of iLQR: the local quadratic model of the cost-to-go and the Riccati
sweep over an LTV model (paper, Preliminaries; notation of :mod:`mjx_surrogate.control.ilqr`).

Tassa-style regularisation mu on V_xx; Q_uu positive definite at every t:

    Q_x  = l_x + A' V_x            Q_u  = l_u + B' V_x
    Q_xx = l_xx + A' V_xx A        Q_uu = l_uu + B' V_xx B        Q_ux = l_ux + B' V_xx A
    Q~_uu = Q_uu + mu B'B          Q~_ux = Q_ux + mu B'A          (regularised: the step only)
    k = argmin_{lo <= k <= hi} 1/2 k' Q~_uu k + Q_u' k   (box QP, projected Newton)
    K = -Q~_uu^-1 Q~_ux on the free controls, 0 on clamped ones
    V_x  = Q_x + K' Q_uu k + K' Q_u + Q_ux' k
    V_xx = Q_xx + K' Q_uu K + K' Q_ux + Q_ux' K
    dV   = (sum k' Q_u, sum 1/2 k' Q_uu k)

V and dV use the plain Q terms: the value of the regularised policy under the model. With
the regularised terms there, V_xx tends to -mu A'B (B'B)^-1 B'A as mu grows, goes
indefinite and makes every later Q~_uu fail (seen on swimmer6, where B is small).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from mjx_surrogate.cost import Cost, hessian_and_gradient, stage_inputs
from mjx_surrogate.linalg import spd_solve


def box_qp(
    Quu: jax.Array, Qu: jax.Array, lo: jax.Array, hi: jax.Array, iters: int = 6
) -> tuple[jax.Array, jax.Array, jax.Array]:
    """min 1/2 k'Quu k + Qu'k s.t. lo <= k <= hi by projected Newton; returns (k, free mask,
    ok), ok = Quu positive definite (from the unconstrained solve that starts the search)."""
    n = Qu.shape[0]
    eye = jnp.eye(n, dtype=Qu.dtype)
    obj = lambda x: 0.5 * x @ Quu @ x + Qu @ x  # noqa: E731
    steps = 0.5 ** jnp.arange(6, dtype=Qu.dtype)

    def free_set(x):
        g = Qu + Quu @ x
        clamped = ((x <= lo) & (g > 0)) | ((x >= hi) & (g < 0))
        return ~clamped, g

    def body(_, x):
        free, g = free_set(x)
        H = jnp.where(free[:, None] & free[None, :], Quu, eye)
        d, _ = spd_solve(H, jnp.where(free, -g, 0.0))
        cands = jnp.clip(x[None] + steps[:, None] * d[None], lo, hi)
        vals = jax.vmap(obj)(cands)
        best = cands[jnp.argmin(vals)]
        return jnp.where(jnp.min(vals) < obj(x), best, x)

    x0, ok = spd_solve(Quu, Qu)
    x = jax.lax.fori_loop(0, iters, body, jnp.clip(-x0, lo, hi))
    return x, free_set(x)[0], ok


def backward_pass(A, B, lx, lu, lxx, luu, lux, VxT, VxxT, U, lo, hi, mu):
    """Riccati sweep. Returns k [T, nu], K [T, nu, nx], dV = (sum k'Q_u, sum 1/2 k'Q_uu k),
    ok (the regularised Q~_uu positive definite at every t) and reg, the largest share of
    the regularisation in the step's curvature, max_t ||mu B'B|| / ||Q_uu|| (Frobenius;
    reg <= 1: the step is within a factor of about 2 of the Newton step). Without any finite limit
    the box QP is skipped: one solve per t gives k and K."""
    bounded = jnp.any(jnp.isfinite(lo) | jnp.isfinite(hi))

    def body(carry, inp):
        Vx, Vxx, ok = carry
        At, Bt, lxt, lut, lxxt, luut, luxt, ut = inp
        Qx = lxt + At.T @ Vx
        Qu = lut + Bt.T @ Vx
        Qxx = lxxt + At.T @ Vxx @ At
        Quu = luut + Bt.T @ Vxx @ Bt
        Qux = luxt + Bt.T @ Vxx @ At
        Quu = 0.5 * (Quu + Quu.T)
        # The regularised pair only shapes the step (k, K); V and dV use the plain Q terms.
        Quu_r = Quu + mu * Bt.T @ Bt
        Qux_r = Qux + mu * Bt.T @ At

        def boxed():
            kt, free, ok = box_qp(Quu_r, Qu, lo - ut, hi - ut)
            Hf = jnp.where(free[:, None] & free[None, :], Quu_r, jnp.eye(Qu.shape[0], dtype=Qu.dtype))
            return kt, -spd_solve(Hf, jnp.where(free[:, None], Qux_r, 0.0))[0], ok

        def unbounded():  # no finite limit: one solve gives k, K and the definiteness test
            sol, ok = spd_solve(Quu_r, jnp.concatenate([Qu[:, None], Qux_r], axis=1))
            return -sol[:, 0], -sol[:, 1:], ok

        kt, Kt, ok_t = jax.lax.cond(bounded, boxed, unbounded)
        Vx_new = Qx + Kt.T @ Quu @ kt + Kt.T @ Qu + Qux.T @ kt
        Vxx_new = Qxx + Kt.T @ Quu @ Kt + Kt.T @ Qux + Qux.T @ Kt
        Vxx_new = 0.5 * (Vxx_new + Vxx_new.T)
        dv = jnp.stack([kt @ Qu, 0.5 * kt @ Quu @ kt])
        ok_t = ok_t & jnp.all(jnp.isfinite(Kt)) & jnp.all(jnp.isfinite(kt))
        reg_t = mu * jnp.linalg.norm(Bt.T @ Bt) / jnp.maximum(jnp.linalg.norm(Quu), jnp.finfo(Quu.dtype).tiny)
        return (Vx_new, Vxx_new, ok & ok_t), (kt, Kt, dv, reg_t)

    (_, _, ok), (k, K, dv, reg) = jax.lax.scan(
        body, (VxT, VxxT, jnp.array(True)), (A, B, lx, lu, lxx, luu, lux, U), reverse=True
    )
    return k, K, dv.sum(0), ok, jnp.max(reg)


def tvlqr_gains(A, B, lx, lu, lxx, luu, lux, VxT, VxxT, U, lo, hi, mu):
    """The Riccati sweep of a nominal taken as final (k = 0): K [T, nu, nx] as in
    :func:`backward_pass`, controls clamped where U sits on a limit and Q_u pushes
    outwards, and ok (every regularised Q~_uu on the free controls positive definite)."""

    def body(carry, inp):
        Vx, Vxx, ok = carry
        At, Bt, lxt, lut, lxxt, luut, luxt, ut = inp
        Qx, Qu = lxt + At.T @ Vx, lut + Bt.T @ Vx
        Qxx = lxxt + At.T @ Vxx @ At
        Quu = luut + Bt.T @ Vxx @ Bt
        Qux = luxt + Bt.T @ Vxx @ At
        Quu = 0.5 * (Quu + Quu.T)
        free = ~(((ut <= lo) & (Qu > 0)) | ((ut >= hi) & (Qu < 0)))
        eye = jnp.eye(Qu.shape[0], dtype=Qu.dtype)
        H = jnp.where(free[:, None] & free[None, :], Quu + mu * Bt.T @ Bt, eye)
        sol, ok_t = spd_solve(H, jnp.where(free[:, None], Qux + mu * Bt.T @ At, 0.0))
        Kt = -sol
        Vxx_new = Qxx + Kt.T @ Quu @ Kt + Kt.T @ Qux + Qux.T @ Kt
        ok_t = ok_t & jnp.all(jnp.isfinite(Kt))
        return (Qx + Kt.T @ Qu, 0.5 * (Vxx_new + Vxx_new.T), ok & ok_t), Kt

    inputs = (A, B, lx, lu, lxx, luu, lux, U)
    (_, _, ok), K = jax.lax.scan(body, (VxT, VxxT, jnp.array(True)), inputs, reverse=True)
    return K, ok


def cost_derivatives(cost: Cost, X: jax.Array, U: jax.Array):
    """l_x [T, nx], l_u [T, nu], l_xx, l_uu, l_ux and terminal V_x, V_xx by autodiff (or
    the cost's own ``derivatives``)."""
    if cost.derivatives is not None:
        return cost.derivatives(X, U)
    running = hessian_and_gradient(cost.running, (0, 1))
    ((lxx, _), (lux, luu)), (lx, lu) = jax.vmap(running)(*stage_inputs(cost, X, U))
    VxxT, VxT = hessian_and_gradient(cost.terminal, 0)(X[-1])
    return lx, lu, lxx, luu, lux, VxT, VxxT


def zero_cost_derivatives(cost: Cost, X: jax.Array, U: jax.Array):
    """Zeros in the shapes and dtypes of :func:`cost_derivatives` at X, U, the second
    derivatives not traced (their trace, for a free joint's quaternion error, is costly):
    autodiff gives each derivative the dtype of the gradient it differentiates (l_x, l_xx,
    V_x, V_xx: X's; l_u, l_uu, l_ux: U's). A cost's own ``derivatives`` are asked for their
    shapes."""
    if cost.derivatives is not None:
        shapes = jax.eval_shape(cost.derivatives, X, U)
        return jax.tree.map(lambda a: jnp.zeros(a.shape, a.dtype), shapes)
    (T, nu), nx, x, u = U.shape, X.shape[-1], X.dtype, U.dtype
    shapes = (((T, nx), x), ((T, nu), u), ((T, nx, nx), x), ((T, nu, nu), u), ((T, nu, nx), u))
    return tuple(jnp.zeros(shape, dtype) for shape, dtype in shapes + (((nx,), x), ((nx, nx), x)))
