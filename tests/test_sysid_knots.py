"""Identification at every k-th step, interpolated between (``sysid.every``)."""

from types import SimpleNamespace
from typing import Callable, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mjx_surrogate.identification import sysid
from mjx_surrogate.identification.sysid_knots import interpolate, knot_times

B_QUAD = jnp.asarray([[1.0], [0.5]])


def quadratic_step(x, u):
    """A(x) = diag(1 + x): central differences are exact, and A_t is linear in X_t."""
    return x + 0.5 * x**2 + B_QUAD @ u


@pytest.mark.parametrize(
    ("T", "every", "knots"),
    [(10, 3, [0, 3, 6, 9]), (10, 4, [0, 4, 8, 9]), (5, 1, [0, 1, 2, 3, 4]), (3, 7, [0, 2])],
)
def test_knots_start_at_zero_end_at_the_last_step(T, every, knots):
    assert knot_times(T, every).tolist() == knots


def test_interpolation_is_exact_on_affine_values_and_at_the_knots():
    T, S = 11, knot_times(11, 4)  # 0 4 8 10
    V = jnp.asarray(np.random.default_rng(1).standard_normal((T, 2, 3)))
    affine = V[0] + jnp.arange(T)[:, None, None] * V[1]
    np.testing.assert_allclose(interpolate(affine[S], S, T), affine, atol=1e-12)
    np.testing.assert_allclose(interpolate(V[S], S, T)[S], V[S], atol=0)


def test_knotted_central_differences_recover_jacobians_linear_in_t():
    """X_t linear in t makes A_t = diag(1 + X_t) linear in t: identifying at the knots and
    interpolating gives every A_t exactly; against the plain scheme it simulates 4/10."""
    T, every = 10, 3
    X = jnp.linspace(jnp.array([0.1, -0.2]), jnp.array([0.7, 0.4]), T + 1)
    U = jnp.zeros((T, 1))
    K = jnp.zeros((T, 1, 2))
    p = sysid.SysIdParams(sigma_x=0.1, sigma_u=0.1, scheme="central_difference", n_samples=6, every=every)
    system = SimpleNamespace(step=quadratic_step)
    A, B = jax.jit(sysid.ltv_linearize(system, p))(X, U, K, jax.random.key(0))
    A_true = jax.vmap(jnp.diag)(1 + X[:-1])
    np.testing.assert_allclose(A, A_true, atol=1e-10)
    np.testing.assert_allclose(B, jnp.broadcast_to(B_QUAD, (T, 2, 1)), atol=1e-10)
    full = p.replace(every=1)
    assert sysid.steps_per_identification(p, T) == 2 * 6 * 4
    assert sysid.steps_per_identification(full, T) == 2 * 6 * T


def test_a_rollout_scheme_cannot_skip_steps():
    from mjx_surrogate.errors import ConfigError
    from mjx_surrogate.runs.config import Config, SysIdConfig
    from mjx_surrogate.runs.validation import validate_static

    with pytest.raises(ConfigError, match="sysid.every"):
        validate_static(Config(sysid=SysIdConfig(scheme="rollout", every=2)))
    with pytest.raises(ConfigError, match="sysid.every"):
        validate_static(Config(sysid=SysIdConfig(every=0)))


class BlackBox(NamedTuple):  # hashable: solve_d2c takes the system as a static argument
    step: Callable
    closed_loop: Callable | None = None
    mesh: None = None


def pendulum(x, u):
    """A damped pendulum with a cubic spring, dt 0.05: Jacobians that vary along t."""
    th, om = x
    return jnp.stack([th + 0.05 * om, om + 0.05 * (-9.81 * jnp.sin(th) - 0.1 * om - 0.5 * th**3 + u[0])])


@pytest.mark.slow
@pytest.mark.parametrize("refine_tol", [0.0, 1e-2])
def test_coarse_then_fine_ends_on_every_step_models_at_the_full_schemes_optimum(refine_tol):
    """A solve with every=4 hands over to every-step identification before it stops: the
    same optimum as every=1, and no minimum declared on an interpolated model."""
    from mjx_surrogate.control.d2c import solve_d2c
    from mjx_surrogate.control.ilqr import ILQRParams
    from mjx_surrogate.tasks import Task

    T = 40
    system = BlackBox(pendulum)
    goal = jnp.array([jnp.pi, 0.0])
    inf = jnp.full(1, jnp.inf)
    z = jnp.zeros((0, 3))
    task = Task(
        x0=jnp.zeros(2), x_goal=goal, Q=0.2 * jnp.eye(2), Q_f=100.0 * jnp.eye(2), R=0.02 * jnp.eye(1),
        u_min=-inf, u_max=inf, u_ref=jnp.zeros(1), targets=z, weights=jnp.zeros(0),
        final_weights=jnp.zeros(0), T=T,
    )  # fmt: skip
    params = ILQRParams(max_iter=300, rel_tol=1e-10, sysid_refine_tol=refine_tol)
    p1 = sysid.SysIdParams(sigma_x=1e-5, sigma_u=1e-5, scheme="forward_difference", n_samples=3)
    p4 = p1.replace(every=4)
    full = solve_d2c(system, task, jnp.zeros((T, 1)), jax.random.key(0), params, p1)
    knotted = solve_d2c(system, task, jnp.zeros((T, 1)), jax.random.key(0), params, p4)
    assert bool(full.converged) and bool(knotted.converged)
    it = int(knotted.iterations)
    ident = np.asarray(knotted.identified)[:it]
    assert ident[0] == 1 and ident[ident > 0][-1] == 2  # coarse first, fine at the end
    assert np.all(np.diff(ident[ident > 0]) >= 0)  # never back to coarse
    np.testing.assert_allclose(float(knotted.cost), float(full.cost), rtol=1e-7)
