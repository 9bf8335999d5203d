"""LTV identification: exact on linear systems (every scheme), close to jacfwd on MuJoCo;
jacfwd through MJX against finite differences."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mjx_surrogate.identification import sysid
from mjx_surrogate.trajectory import simulate

rng = np.random.default_rng(0)
A_TRUE = np.eye(3) + 0.1 * rng.standard_normal((3, 3))
B_TRUE = rng.standard_normal((3, 2))


def linear_step(x, u):
    return jnp.asarray(A_TRUE) @ x + jnp.asarray(B_TRUE) @ u


@pytest.mark.parametrize("scheme", sysid.SCHEMES)
def test_linear_system_recovered_to_roundoff(scheme):
    T = 12
    U = jnp.asarray(rng.standard_normal((T, 2)))
    X = simulate(linear_step, jnp.ones(3), U)
    K = jnp.asarray(0.1 * rng.standard_normal((T, 2, 3)))
    p = sysid.SysIdParams(sigma_x=0.1, sigma_u=0.1, scheme=scheme, n_samples=12)
    key = jax.random.key(3)
    batched = lambda x0, U: jax.vmap(simulate, in_axes=(None, 0, 0))(linear_step, x0, U)  # noqa
    if scheme == "central_difference":
        A, B = sysid.central_difference(linear_step, X, U, key, p)
    elif scheme == "forward_difference":
        A, B = sysid.forward_difference(linear_step, X, U, key, p)
    elif scheme == "rollout":
        A, B = sysid.open_loop_rollouts(batched, X, U, key, p)
    else:
        A, B = sysid.closed_loop_rollouts(linear_step, X, U, K, key, p)
    assert A.shape == (T, 3, 3) and B.shape == (T, 3, 2) and A.dtype == jnp.float64
    np.testing.assert_allclose(A, np.broadcast_to(A_TRUE, A.shape), atol=1e-10)
    np.testing.assert_allclose(B, np.broadcast_to(B_TRUE, B.shape), atol=1e-10)


@pytest.mark.parametrize("scheme", ["central_difference", "forward_difference"])
def test_orthogonal_minimal_design_recovers_a_linear_system(scheme):
    # nx + nu = 5 samples per time step: the fewest that determine [A_t B_t]
    T = 6
    U = jnp.asarray(rng.standard_normal((T, 2)))
    X = simulate(linear_step, jnp.ones(3), U)
    p = sysid.SysIdParams(sigma_x=0.1, sigma_u=0.1, scheme=scheme, n_samples=5, design="orthogonal")
    fn = sysid.central_difference if scheme == "central_difference" else sysid.forward_difference
    A, B = fn(linear_step, X, U, jax.random.key(5), p)
    np.testing.assert_allclose(A, np.broadcast_to(A_TRUE, A.shape), atol=1e-10)
    np.testing.assert_allclose(B, np.broadcast_to(B_TRUE, B.shape), atol=1e-10)


@pytest.mark.parametrize("design", ["gaussian", "orthogonal"])
@pytest.mark.parametrize("scheme", ["central_difference", "forward_difference"])
def test_a_given_start_identifies_b0_alone(scheme, design):
    """perturb_x0 off: t = 0 from control perturbations only (A_0 = 0, B_0 exact), every
    other step bit for bit as with the start perturbed (the same draws)."""
    T = 6
    U = jnp.asarray(rng.standard_normal((T, 2)))
    X = simulate(linear_step, jnp.ones(3), U)
    fn = sysid.central_difference if scheme == "central_difference" else sysid.forward_difference
    p = sysid.SysIdParams(sigma_x=0.1, sigma_u=0.1, scheme=scheme, n_samples=10, design=design)
    A, B = fn(linear_step, X, U, jax.random.key(5), p.replace(perturb_x0=False))
    A1, B1 = fn(linear_step, X, U, jax.random.key(5), p)
    assert np.all(np.asarray(A[0]) == 0.0)
    np.testing.assert_allclose(B[0], B_TRUE, atol=1e-10)
    np.testing.assert_array_equal(A[1:], A1[1:])
    np.testing.assert_array_equal(B[1:], B1[1:])
    np.testing.assert_allclose(A1[0], A_TRUE, atol=1e-10)


LO = -0.2  # a limit of coordinate 0 in kinked_step


def kinked_step(x, u):
    """linear_step plus a one-sided force on coordinate 0 below LO, as a joint limit's."""
    return linear_step(x, u) + jnp.asarray([3.0, -2.0, 1.0]) * jnp.minimum(x[0] - LO, 0.0)


@pytest.mark.parametrize("design", ["gaussian", "orthogonal"])
@pytest.mark.parametrize("scheme", ["central_difference", "forward_difference"])
def test_a_coordinate_at_its_limit_is_held_and_the_rest_stay_exact(scheme, design):
    """The nominal's coordinate 0 sits 0.3 sigma above its limit at every step: perturbed
    across the kink, least squares spreads the misfit over every coefficient; held, the
    others are exact to round-off and A's column 0 is 0."""
    T, sigma = 6, 0.1
    U = jnp.asarray(rng.standard_normal((T, 2)))
    X = jnp.asarray(rng.standard_normal((T + 1, 3))).at[:, 0].set(LO + 0.3 * sigma)
    fn = sysid.central_difference if scheme == "central_difference" else sysid.forward_difference
    p = sysid.SysIdParams(sigma_x=sigma, sigma_u=sigma, scheme=scheme, n_samples=10, design=design)
    limits = (np.array([LO, -np.inf, -np.inf]), np.array([5.0, np.inf, np.inf]))
    A, B = fn(kinked_step, X, U, jax.random.key(5), p, None, limits)
    assert np.all(np.asarray(A[:, :, 0]) == 0.0)
    np.testing.assert_allclose(A[:, :, 1:], np.broadcast_to(A_TRUE[:, 1:], (T, 3, 2)), atol=1e-10)
    np.testing.assert_allclose(B, np.broadcast_to(B_TRUE, B.shape), atol=1e-10)
    A0, B0 = fn(kinked_step, X, U, jax.random.key(5), p)  # perturbed across the kink
    assert np.abs(np.asarray(B0) - B_TRUE).max() > 1e-3
    # a coordinate away from its limit (here 10 sigma) is perturbed as before, bit for bit
    far = X.at[:, 0].set(LO + 10 * sigma)
    np.testing.assert_array_equal(
        fn(kinked_step, far, U, jax.random.key(5), p, None, limits)[0],
        fn(kinked_step, far, U, jax.random.key(5), p)[0],
    )


def test_joint_limits_of_a_model_name_the_limited_hinges_and_slides():
    import mujoco

    from mjx_surrogate.systems.system import joint_limits

    m = mujoco.MjModel.from_xml_string(
        """<mujoco><compiler angle="radian"/><worldbody><body><freejoint/><geom size=".1"/>
        <body><joint name="h" type="hinge" range="-1 2" margin="0.1"/><geom size=".1"/>
        <body><joint type="ball" range="0 1"/><geom size=".1"/>
        <body><joint type="slide" range="0 0.5"/><joint type="hinge"/><geom size=".1"/>
        </body></body></body></body></worldbody></mujoco>"""
    )
    lo, hi = joint_limits(m)
    nx = m.nq + m.nv
    assert lo.shape == hi.shape == (nx,)
    limited = {7: (-0.9, 1.9), 12: (0.0, 0.5)}  # after the free joint (7) and the ball (4)
    for i in range(nx):
        want = limited.get(i, (-np.inf, np.inf))
        assert (lo[i], hi[i]) == pytest.approx(want), i
    assert (
        joint_limits(
            mujoco.MjModel.from_xml_string(
                '<mujoco><worldbody><body><joint type="hinge"/><geom size=".1"/></body></worldbody></mujoco>'
            )
        )
        is None
    )


@pytest.mark.parametrize("n", [5, 10, 7])
def test_orthogonal_designs_give_numpy_least_squares_on_a_nonlinear_step(n):
    """Whole orthogonal blocks (n a multiple of nx + nu = 5: Z'Z diagonal, the regression a
    product) and a partial block (the general solve) give float64 NumPy's least-squares
    fit of the same samples, with unequal sigma_x and sigma_u."""
    step = lambda x, u: jnp.asarray(A_TRUE) @ jnp.sin(x) + jnp.asarray(B_TRUE) @ (u + u**3)  # noqa: E731
    T = 4
    U = jnp.asarray(rng.standard_normal((T, 2)))
    X = simulate(step, jnp.ones(3), U)
    p = sysid.SysIdParams(0.3, 0.05, scheme="forward_difference", n_samples=n, design="orthogonal")
    assert sysid.diagonal_gram(p, 5) == (n % 5 == 0)
    key = jax.random.key(7)
    A, B = sysid.forward_difference(step, X, U, key, p)
    dx, du = (np.asarray(a) for a in sysid._one_step_perturbations(key, T, 3, 2, p, jnp.float64))
    for t in range(T):
        Z = np.concatenate([dx[:, t], du[:, t]], axis=-1)  # [n, 5]
        Y = np.stack([step(X[t] + dx[i, t], U[t] + du[i, t]) for i in range(n)]) - step(X[t], U[t])
        W = np.linalg.lstsq(Z, Y, rcond=None)[0].T
        np.testing.assert_allclose(A[t], W[:, :3], rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(B[t], W[:, 3:], rtol=1e-9, atol=1e-12)


def test_lstsq_matches_float64_numpy():
    Z = rng.standard_normal((4, 30, 5)) * np.array([1e-3, 1e-3, 1e-3, 1.0, 10.0])
    Y = rng.standard_normal((4, 30, 3))
    A, B = sysid.lstsq_ltv(jnp.asarray(Z), jnp.asarray(Y), 3)
    for t in range(4):
        W = np.linalg.lstsq(Z[t], Y[t], rcond=None)[0].T
        np.testing.assert_allclose(A[t], W[:, :3], rtol=1e-8)
        np.testing.assert_allclose(B[t], W[:, 3:], rtol=1e-8)


# jacfwd through MJX compiles for tens of seconds: one program per step function and shape
_exact_jacobians = jax.jit(sysid.exact_jacobians, static_argnums=0)


@pytest.mark.slow
def test_exact_jacobians_match_finite_differences(systems):
    """``jax.jacfwd`` through the MJX step, against central differences of it (a model with
    contacts: tests/test_backend_mjx.py; the cartpole's program alone takes ~25 s to build)."""
    s = systems("pendulum", "mjx")
    X = jnp.asarray(rng.standard_normal((11, s.nx)) * 0.5)  # the shapes of the scheme test's
    U = jnp.asarray(rng.standard_normal((10, s.nu)))  # trajectory: one compiled program for both
    A, B = _exact_jacobians(s.mjx_step, X, U)
    step = jax.jit(s.mjx_step)
    eps = 1e-6
    for t in range(2):
        fd_A = np.stack(
            [(step(X[t] + eps * e, U[t]) - step(X[t] - eps * e, U[t])) / (2 * eps) for e in np.eye(s.nx)],
            axis=1,
        )
        fd_B = np.stack(
            [(step(X[t], U[t] + eps * e) - step(X[t], U[t] - eps * e)) / (2 * eps) for e in np.eye(s.nu)],
            axis=1,
        )
        np.testing.assert_allclose(A[t], fd_A, atol=1e-7)
        np.testing.assert_allclose(B[t], fd_B, atol=1e-7)


@pytest.mark.parametrize(
    "scheme,sigma,tol",
    [
        ("central_difference", 1e-4, 1e-6),
        ("forward_difference", 1e-4, 1e-3),
        ("forward_difference", 1e-7, 1e-6),
    ],
)
@pytest.mark.slow
def test_difference_schemes_close_to_exact_on_mujoco(systems, scheme, sigma, tol):
    """Central differences are second-order accurate, forward differences first-order:
    at sigma 1e-4 only the central scheme reaches 1e-6; forward needs a smaller sigma."""
    s = systems("pendulum", "native")  # the black box: no derivatives
    T = 10
    U = jnp.asarray(rng.standard_normal((T, 1)))
    X = jax.jit(s.rollout)(jnp.array([[3.0, 0.0]]), U[None])[0]
    p = sysid.SysIdParams(sigma_x=sigma, sigma_u=sigma, n_samples=10, scheme=scheme)
    fit = getattr(sysid, scheme)
    A, B = jax.jit(lambda X, U, k: fit(s.step, X, U, k, p))(X, U, jax.random.key(0))
    Ae, Be = _exact_jacobians(systems("pendulum", "mjx").mjx_step, X, U)
    rel = np.linalg.norm(np.concatenate([A - Ae, B - Be], -1)) / np.linalg.norm(np.concatenate([Ae, Be], -1))
    assert rel < tol
    if scheme == "forward_difference" and sigma == 1e-4:
        assert rel > 1e-6  # first-order error is visible at this sigma


@pytest.mark.slow
def test_finite_difference_jacobians_match_jacfwd_on_mujoco():
    import jax
    import jax.numpy as jnp
    import numpy as np

    from mjx_surrogate.identification.sysid import exact_jacobians, finite_difference_jacobians
    from mjx_surrogate.runs.config import Config, SystemConfig, TaskConfig
    from mjx_surrogate.runs.resolution import resolve

    res = resolve(
        Config(system=SystemConfig(name="pendulum", backend="mjx"), task=TaskConfig(preset="pendulum_d2c"))
    )
    s, task = res.system, res.task
    U = 0.3 * jax.random.normal(jax.random.key(0), (5, 1), task.x0.dtype)
    X = jax.jit(lambda u: jax.lax.scan(lambda x, ut: (s.step(x, ut), s.step(x, ut)), task.x0, u)[1])(U)
    X = jnp.concatenate([task.x0[None], X])
    A, B = jax.jit(lambda X, U: finite_difference_jacobians(s.step, X, U))(X, U)
    Ae, Be = jax.jit(lambda X, U: exact_jacobians(s.step, X, U))(X, U)
    assert np.allclose(A, Ae, atol=1e-7) and np.allclose(B, Be, atol=1e-7)
    assert not np.allclose(A, 0 * Ae, atol=1e-3)  # non-trivial
