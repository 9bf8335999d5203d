"""The solver's view of a cost: running ``l(x, u)`` and terminal ``l_f(x)`` functions.

    J(X, U) = sum_{t<T} l(x_t, u_t) + l_f(x_T),    X [T+1, nx], U [T, nu]

Derivatives are taken by autodiff (:func:`mjx_surrogate.control.riccati.cost_derivatives`), so a cost
term is any differentiable function, unless the cost brings its own ``derivatives`` (the
tasks' point goals use a Gauss-Newton Hessian, :mod:`mjx_surrogate.tasks`).
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import jax
import jax.numpy as jnp

BLOWUP = 1e8  # |x| beyond this counts as a blown-up trajectory


class Cost(NamedTuple):
    """running(x[nx], u[nu]) -> scalar; terminal(x[nx]) -> scalar.

    derivatives(X [T+1, nx], U [T, nu]) -> (l_x, l_u, l_xx, l_uu, l_ux, V_x, V_xx), the
    shapes of :func:`mjx_surrogate.control.riccati.cost_derivatives`; None: exact, by autodiff.
    timed: the running cost depends on the stage, ``running(x, u, t)`` with t the stage
    index (an int32 scalar, 0 .. T-1), as a horizon that ends before its last stage does
    (:func:`mjx_surrogate.tasks.at_step`)."""

    running: Callable[..., jax.Array]
    terminal: Callable[[jax.Array], jax.Array]
    derivatives: Callable | None = None
    timed: bool = False


def stage_inputs(cost: Cost, X: jax.Array, U: jax.Array) -> tuple:
    """The running cost's arguments at every stage, stacked: (X[:-1], U), and the stage
    indices [T] for a timed cost."""
    return (X[:-1], U, jnp.arange(U.shape[0], dtype=jnp.int32)) if cost.timed else (X[:-1], U)


def trajectory_cost(cost: Cost, X: jax.Array, U: jax.Array) -> jax.Array:
    """J of X [T+1, nx], U [T, nu]; +inf if X is not finite or blew up (|x| > BLOWUP)."""
    J = jax.vmap(cost.running)(*stage_inputs(cost, X, U)).sum() + cost.terminal(X[-1])
    bad = ~jnp.all(jnp.isfinite(X)) | (jnp.max(jnp.abs(X)) > BLOWUP) | ~jnp.isfinite(J)
    return jnp.where(bad, jnp.inf, J)


def hessian_and_gradient(f: Callable, argnums: int | tuple[int, ...] = 0) -> Callable:
    """args -> (Hessian, gradient) of the scalar f, as ``jax.hessian`` and ``jax.grad`` give
    them, from one forward-over-reverse program whose primal is the gradient (a separate
    ``jax.grad`` would trace and compile the reverse pass, and the cost's code, once more)."""
    grad = jax.grad(f, argnums=argnums)
    return jax.jacfwd(lambda *args: (lambda g: (g, g))(grad(*args)), argnums=argnums, has_aux=True)
