"""Local linear time-varying (LTV) identification by closed-form least squares.

Every scheme ends in the same regression, solved for all t at once:

    dx_{t+1} ~= A_t dx_t + B_t du_t,   [A_t B_t]' = argmin_W || Z_t W - Y_t ||^2

with Z_t [n, nx+nu] the perturbations and Y_t [n, nx] the responses. The sums G = Z'Z and
F = Z'Y are the regression's sufficient statistics: with the samples spread over the
devices of ``system.mesh`` each device sums its own and one ``psum`` adds them
(:mod:`mjx_surrogate.sharding`). Columns of Z are then scaled to unit RMS (G to a unit
diagonal) and the normal equations G W = F solved by elimination (:mod:`mjx_surrogate.linalg`:
no batched LAPACK, which can deadlock jaxlib 0.10 on CPU). With random perturbations and
n >= nx + nu the scaled Gram matrix is well conditioned. With ``significance`` > 0 the
coefficients that a t-test on the regression's residuals cannot tell from zero are zero
(:mod:`mjx_surrogate.identification.sysid_significance`); with ``noise_floor`` > 0, those below the
difference quotients' resolution (:func:`below_resolution`).

Schemes (``SysIdParams.scheme``), registered in :data:`SCHEMES` (a new scheme is one
function plus one :func:`register_scheme` call; docs/extending.md):
* ``rollout``: the paper's: n open-loop rollouts from x0 + dx0 under U + dU;
* ``closed_loop``: the same under the current feedback u = U + dU + K (x - X), which
  keeps the perturbations from lining up with unstable directions;
* ``central_difference``: D2C 2.0: one step from (x_t +- dx, u_t +- du) at every t,
  Y = (f+ - f-) / 2; exact to second order and independent across t;
* ``forward_difference``: one step from (x_t + dx, u_t + du) and one from (x_t, u_t),
  Y = f+ - f0: (n + 1) T calls instead of 2 n T, exact to first order only (use a small
  sigma in float64).
"""

from __future__ import annotations

from functools import partial
from typing import Any, Callable, NamedTuple

import jax
import jax.numpy as jnp
from flax import struct
from jax.sharding import Mesh

from mjx_surrogate import sharding
from mjx_surrogate.errors import registered
from mjx_surrogate.identification import sysid_knots, sysid_significance
from mjx_surrogate.linalg import spd_solve, unit_diagonal
from mjx_surrogate.trajectory import feedback_rollout

LinearizeFn = sysid_knots.LinearizeFn  # (X [T+1, nx], U [T, nu], K [T, nu, nx], key) -> (A, B)


@struct.dataclass
class SysIdParams:
    """scheme and n_samples are static; sigma_x, sigma_u (perturbation std) are traced."""

    sigma_x: float = 1e-3
    sigma_u: float = 1e-3
    scheme: str = struct.field(pytree_node=False, default="central_difference")
    n_samples: int = struct.field(pytree_node=False, default=20)
    every: int = struct.field(pytree_node=False, default=1)  # identify every k-th step (sysid_knots)
    design: str = struct.field(pytree_node=False, default="gaussian")  # or "orthogonal"
    noise_floor: float = struct.field(pytree_node=False, default=0.0)  # see :func:`below_resolution`
    perturb_x0: bool = struct.field(pytree_node=False, default=True)  # one-step schemes, t = 0
    hold_limits: bool = struct.field(pytree_node=False, default=False)  # see :func:`hold_at_limits`
    significance: float = struct.field(pytree_node=False, default=0.0)  # t_min, sysid_significance
    rank_tol: float = 1e-8  # reduced scheme: energy left out of the snapshot basis (sysid_reduced)
    settings: Any = struct.field(pytree_node=False, default=None)  # the scheme's own (a frozen dataclass)


def normal_equations(
    Z: jax.Array, Y: jax.Array, w: jax.Array | None, diagonal: bool = False
) -> tuple[jax.Array, jax.Array]:
    """Weighted sufficient statistics of the regression, summed over samples:
    Z [T, n, m], Y [T, n, nx], w [n] (None: all ones) -> G = Z'WZ [T, m, m], F = Z'WY
    [T, m, nx]. A sample of weight 0 (padding) contributes nothing, even if non-finite.
    ``diagonal``: the design makes Z'Z diagonal (:func:`diagonal_gram`); G is then only its
    diagonal [T, m]."""
    if w is not None:
        keep = (w > 0)[None, :, None]
        Z, Y = jnp.where(keep, Z, 0.0), jnp.where(keep, Y, 0.0)
    Zw = Z if w is None else Z * w[None, :, None]
    G = jnp.einsum("tni,tni->ti", Zw, Z) if diagonal else jnp.einsum("tni,tnj->tij", Zw, Z)
    return G, jnp.einsum("tni,tnj->tij", Zw, Y)


def solve_normal_equations(G: jax.Array, F: jax.Array, nx: int) -> tuple[jax.Array, jax.Array]:
    """G [T, m, m] (or its diagonal [T, m]: a diagonal Gram matrix), F [T, m, nx] -> A [T,
    nx, nx], B [T, nx, m - nx]. Rows and columns are scaled to a unit diagonal first (the
    columns of Z to unit RMS), then solved; a diagonal G needs no elimination."""
    if G.ndim == 2:
        W = F / jnp.where(G > 0, G, 1.0)[:, :, None]
    else:
        # a regressor that never moved (dx_0 with perturb_x0 off) gets coefficient 0
        Gs, s, _ = unit_diagonal(G)
        Fs = F / s[:, :, None]
        W = jax.vmap(lambda g, f: spd_solve(g, f)[0])(Gs, Fs) / s[:, :, None]  # [T, m, nx]
    Wt = jnp.swapaxes(W, 1, 2)  # [T, nx, m]
    return Wt[:, :, :nx], Wt[:, :, nx:]


def diagonal_gram(p: SysIdParams, m: int) -> bool:
    """Whether one-step samples of design ``p`` make Z'Z diagonal for m regressors: whole
    orthogonal blocks (n a multiple of m), so that Z'Z = (n / m) diag(sigma^2) exactly and
    the regression is a product, [A B]' = diag(Z'Z)^-1 Z'Y (paper, Section 3: a perfectly
    conditioned Gram matrix); its off-diagonal entries would be round-off."""
    return p.design == "orthogonal" and p.n_samples % m == 0


def _statistics(Z: jax.Array, Y: jax.Array, w: jax.Array | None, p: SysIdParams, diagonal: bool = False):
    """(G, F) of :func:`normal_equations`, and with ``p.significance`` > 0 the sum of
    squares S [T, nx] its t-test needs (:mod:`mjx_surrogate.identification.sysid_significance`)."""
    G, F = normal_equations(Z, Y, w, diagonal)
    if p.significance == 0:
        return G, F
    return G, F, sysid_significance.sum_of_squares(Y, w)


def _fit(stats: tuple, nx: int, p: SysIdParams) -> tuple[jax.Array, jax.Array]:
    """A, B from the summed :func:`_statistics` of ``p.n_samples`` samples; with
    ``p.significance`` > 0 the coefficients the data cannot tell from zero are zero."""
    A, B = solve_normal_equations(stats[0], stats[1], nx)
    if p.significance == 0:
        return A, B
    return sysid_significance.drop_insignificant(*stats, A, B, p.n_samples, p.significance)


def lstsq_ltv(Z: jax.Array, Y: jax.Array, nx: int) -> tuple[jax.Array, jax.Array]:
    """Z [T, n, nx+nu], Y [T, n, nx] -> A [T, nx, nx], B [T, nx, nu]."""
    return solve_normal_equations(*normal_equations(Z, Y, None), nx)


def _trajectory_statistics(dX: jax.Array, dU: jax.Array, w: jax.Array | None, p: SysIdParams = SysIdParams()):
    """Statistics of the regression of dX[:, t+1] on [dX[:, t], dU[:, t]] (dX [n, T+1, nx],
    dU [n, T, nu], weights w [n])."""
    Z = jnp.swapaxes(jnp.concatenate([dX[:, :-1], dU], axis=-1), 0, 1)
    return _statistics(Z, jnp.swapaxes(dX[:, 1:], 0, 1), w, p)


@jax.jit
def fit_from_trajectories(dX: jax.Array, dU: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Regress dX[:, t+1] on [dX[:, t], dU[:, t]]: dX [n, T+1, nx], dU [n, T, nu]."""
    G, F = _trajectory_statistics(dX, dU, None)
    return solve_normal_equations(G, F, dX.shape[-1])


def _one_step_perturbations(
    key: jax.Array, T: int, nx: int, nu: int, p: SysIdParams, dtype
) -> tuple[jax.Array, jax.Array]:
    """dx [n, T, nx] ~ N(0, sigma_x^2), du [n, T, nu] ~ N(0, sigma_u^2); drawn [T, n, .]
    (the layout of earlier versions, so a key gives the same samples) and returned with
    the sample axis leading, the axis that is spread over devices. With
    ``p.perturb_x0`` off, dx at t = 0 is zero: x_0 is the task's given start, so dx_0 = 0
    in every rollout and only B_0 matters; A_0 is then 0. (At a start that penetrates the
    floor, the dm_control walker's qpos0, perturbing x_0 corrupted B_0 by 1e4x: D2C
    stalled 26 % above the oracle, and matches it bit for bit without.)"""
    if p.design == "orthogonal":
        scale = jnp.concatenate([jnp.full(nx, p.sigma_x, dtype), jnp.full(nu, p.sigma_u, dtype)])
        z = orthogonal_design(key, T, p.n_samples, nx + nu, dtype) * scale  # [T, n, nx+nu]
        dx, du = z[..., :nx], z[..., nx:]
    else:
        kx, ku = jax.random.split(key)
        dx = p.sigma_x * jax.random.normal(kx, (T, p.n_samples, nx), dtype)
        du = p.sigma_u * jax.random.normal(ku, (T, p.n_samples, nu), dtype)
    if not p.perturb_x0:  # the start is given (dx_0 = 0 in every rollout): identify B_0 alone
        dx = dx.at[0].set(0.0)
    return jnp.swapaxes(dx, 0, 1), jnp.swapaxes(du, 0, 1)


def orthogonal_design(key: jax.Array, T: int, n: int, m: int, dtype) -> jax.Array:
    """[T, n, m]: for each t, the rows of ceil(n / m) random Householder reflections
    I - 2 v v' / (v'v) of R^m, cut to n rows. Each block of m rows is orthonormal, so with
    n = m the scaled regression's Gram matrix is the identity: the fewest samples that
    determine [A_t B_t], perfectly conditioned."""
    blocks = -(-n // m)
    v = jax.random.normal(key, (T, blocks, m), dtype)
    v = v / jnp.linalg.norm(v, axis=-1, keepdims=True)
    H = jnp.eye(m, dtype=dtype) - 2.0 * v[..., :, None] * v[..., None, :]
    return H.reshape(T, blocks * m, m)[:, :n]


def hold_at_limits(dx: jax.Array, X: jax.Array, limits, sigma) -> jax.Array:
    """dx [T, b, nx] with every coordinate of X [T, nx] that lies within 5 sigma of a joint
    limit (``limits``: (lower, upper) [nx], :attr:`System.state_limits`; None: unchanged)
    left unperturbed, so its regressor never moves and its column of A is 0.

    At a limit the one-step map has a kink; perturbations across it are not linear, and
    least squares spreads that misfit over every coefficient of the row. The Franka's
    fingers rest on their limit: their misfit put errors of 0.01-0.04 into the arm's
    coefficients (1e-8 elsewhere) and D2C stopped 3.7 % above the finite-difference oracle,
    short of the goal; with the fingers held it converges to the oracle's cost
    (docs/performance.md)."""
    if limits is None:
        return dx
    lo, hi = (jnp.asarray(a, X.dtype) for a in limits)
    near = (jnp.abs(X - lo) <= 5 * sigma) | (jnp.abs(hi - X) <= 5 * sigma)  # [T, nx]
    return jnp.where(near[:, None, :], 0.0, dx)


def _limits(system, p: SysIdParams):
    """The joint limits the one-step schemes hold at (None: perturb every coordinate)."""
    return getattr(system, "state_limits", None) if p.hold_limits else None


def central_difference(
    step: Callable,
    X: jax.Array,
    U: jax.Array,
    key: jax.Array,
    p: SysIdParams,
    mesh: Mesh | None = None,
    limits=None,
) -> tuple[jax.Array, jax.Array]:
    """D2C 2.0 scheme around the nominal X [T+1, nx], U [T, nu]; 2 n T one-step calls,
    the samples spread over ``mesh``; coordinates at ``limits`` held (:func:`hold_at_limits`)."""
    T, nu = U.shape
    nx = X.shape[-1]

    def stats(samples, w, X, U):
        dx, du = (jnp.swapaxes(a, 0, 1) for a in samples)  # [T, b, .]
        dx = hold_at_limits(dx, X[:-1], limits, p.sigma_x)
        b = dx.shape[1]
        xs = jnp.concatenate([X[:-1, None] + dx, X[:-1, None] - dx], axis=1)  # [T, 2b, nx]
        us = jnp.concatenate([U[:, None] + du, U[:, None] - du], axis=1)
        f = jax.vmap(step)(xs.reshape(-1, nx), us.reshape(-1, nu)).reshape(T, 2 * b, nx)
        Z = jnp.concatenate([dx, du], axis=-1)
        return _statistics(Z, 0.5 * (f[:, :b] - f[:, b:]), w, p, diagonal_gram(p, nx + nu))

    samples = _one_step_perturbations(key, T, nx, nu, p, X.dtype)
    return _fit(sharding.sum_over_batch(stats, mesh, samples, (X, U)), nx, p)


def forward_difference(
    step: Callable,
    X: jax.Array,
    U: jax.Array,
    key: jax.Array,
    p: SysIdParams,
    mesh: Mesh | None = None,
    limits=None,
) -> tuple[jax.Array, jax.Array]:
    """One-sided scheme around X [T+1, nx], U [T, nu]; (n + 1) T one-step calls (plus T
    per extra device); coordinates at ``limits`` held (:func:`hold_at_limits`).

    f(x_t, u_t) is recomputed in the same batch rather than taken from X[t+1], so that a
    simulator whose step depends on more than (x, u) (e.g. a warm-started constraint
    solver) is differenced against itself.
    """
    T, nu = U.shape
    nx = X.shape[-1]

    def stats(samples, w, X, U):
        dx, du = (jnp.swapaxes(a, 0, 1) for a in samples)  # [T, b, .]
        dx = hold_at_limits(dx, X[:-1], limits, p.sigma_x)
        b = dx.shape[1]
        xs = jnp.concatenate([X[:-1, None], X[:-1, None] + dx], axis=1)  # [T, b+1, nx]
        us = jnp.concatenate([U[:, None], U[:, None] + du], axis=1)
        f = jax.vmap(step)(xs.reshape(-1, nx), us.reshape(-1, nu)).reshape(T, b + 1, nx)
        Z = jnp.concatenate([dx, du], axis=-1)
        return _statistics(Z, f[:, 1:] - f[:, :1], w, p, diagonal_gram(p, nx + nu))

    samples = _one_step_perturbations(key, T, nx, nu, p, X.dtype)
    return _fit(sharding.sum_over_batch(stats, mesh, samples, (X, U)), nx, p)


def _rollout_perturbations(key: jax.Array, X: jax.Array, U: jax.Array, p: SysIdParams):
    kx, ku = jax.random.split(key)
    n = p.n_samples
    dx0 = p.sigma_x * jax.random.normal(kx, (n,) + X[0].shape, X.dtype)
    dU = p.sigma_u * jax.random.normal(ku, (n,) + U.shape, U.dtype)
    return dx0, dU


def open_loop_rollouts(
    rollout: Callable, X: jax.Array, U: jax.Array, key: jax.Array, p: SysIdParams, mesh: Mesh | None = None
) -> tuple[jax.Array, jax.Array]:
    """The paper's scheme: rollouts from X[0] + dx0 under U + dU; rollout is batched."""

    def stats(samples, w, X, U):
        dx0, dU = samples
        Xp = rollout(X[0][None] + dx0, U[None] + dU)
        return _trajectory_statistics(Xp - X[None], dU, w, p)

    samples = _rollout_perturbations(key, X, U, p)
    return _fit(sharding.sum_over_batch(stats, mesh, samples, (X, U)), X.shape[-1], p)


def closed_loop_rollouts(
    step: Callable,
    X: jax.Array,
    U: jax.Array,
    K: jax.Array,
    key: jax.Array,
    p: SysIdParams,
    mesh: Mesh | None = None,
) -> tuple[jax.Array, jax.Array]:
    """Rollouts under u_t = U_t + dU_t + K_t (x_t - X_t); regress on the applied du."""

    def stats(samples, w, X, U, K):
        Xp, Us = jax.vmap(lambda dx0, dU: feedback_rollout(step, X[0] + dx0, X, U, K, dU))(*samples)
        return _trajectory_statistics(Xp - X[None], Us - U[None], w, p)

    samples = _rollout_perturbations(key, X, U, p)
    return _fit(sharding.sum_over_batch(stats, mesh, samples, (X, U, K)), X.shape[-1], p)


def exact_jacobians(step: Callable, X: jax.Array, U: jax.Array) -> tuple[jax.Array, jax.Array]:
    """A_t = df/dx, B_t = df/du at (X[t], U[t]) by ``jax.jacfwd`` (needs a differentiable step)."""
    return jax.vmap(jax.jacfwd(step, argnums=(0, 1)))(X[:-1], U)


@partial(jax.jit, static_argnames=("step", "eps"))
def finite_difference_jacobians(
    step: Callable, X: jax.Array, U: jax.Array, eps: float | None = None
) -> tuple[jax.Array, jax.Array]:
    """A_t, B_t by central differences of ``step`` along every coordinate of (x, u):
    2 (nx + nu) T one-step calls in one batch; the error is O(eps^2) plus round-off
    O(machine eps / eps). eps defaults to machine eps^(1/3) (6e-6 in float64)."""
    T, nu = U.shape
    nx = X.shape[-1]
    n = nx + nu
    eps = float(jnp.finfo(X.dtype).eps) ** (1 / 3) if eps is None else eps
    E = eps * jnp.eye(n, dtype=X.dtype)  # [n, n]
    D = jnp.concatenate([E, -E])  # [2n, n]
    xs = X[:-1, None] + D[None, :, :nx]  # [T, 2n, nx]
    us = U[:, None] + D[None, :, nx:]
    f = jax.vmap(step)(xs.reshape(-1, nx), us.reshape(-1, nu)).reshape(T, 2 * n, nx)
    J = jnp.swapaxes((f[:, :n] - f[:, n:]) / (2 * eps), 1, 2)  # [T, nx, n]
    return J[:, :, :nx], J[:, :, nx:]


class IdentificationScheme(NamedTuple):
    """A registered way of identifying the LTV model of a black box.

    make_linearize(system, params) -> linearize(X, U, K, key) -> (A, B): the iLQR's
      ``linearize`` hook; ``system`` offers ``step`` (batched under vmap) and ``rollout``.
    simulated_steps(T, n_samples) -> control steps simulated by one identification
      (a reduced scheme: simulated_steps(T, n_samples, nu)).
    one_step: identifies each t from one-step simulations alone (then ``every`` > 1 may
      skip steps, :mod:`mjx_surrogate.identification.sysid_knots`).
    t_test: applies ``SysIdParams.significance`` (a least-squares scheme does through
      ``_statistics`` and ``_fit``).
    reduced: identifies in a basis of ``n_samples`` columns per step: linearize returns
      (A [T, n, n], B [T, n, nu], V [T+1, nx, n]) (:mod:`mjx_surrogate.identification.sysid_reduced`), and
      n_samples is that largest rank, not a sample count >= nx + nu.
    settings: the scheme's own settings' defaults (a frozen dataclass instance, set as
      ``--sysid.<name>.<field>``); ``make_linearize`` finds the run's values in
      ``params.settings`` (:mod:`mjx_surrogate.runs.extension_settings`).
    """

    make_linearize: Callable[[Any, SysIdParams], LinearizeFn]
    simulated_steps: Callable[[int, int], int]
    description: str = ""
    one_step: bool = False
    t_test: bool = False
    reduced: bool = False
    settings: Any = None


SCHEMES: dict[str, IdentificationScheme] = {}


def register_scheme(name: str, scheme: IdentificationScheme) -> None:
    """Add ``scheme`` under ``name`` (then valid as ``sysid.scheme``)."""
    SCHEMES[name] = scheme


def get_scheme(name: str, field: str = "sysid.scheme") -> IdentificationScheme:
    return registered(SCHEMES, name, field, "identification scheme")


def _mesh(system) -> Mesh | None:
    """The devices ``system`` spreads its batches over (None for any simpler black box)."""
    return getattr(system, "mesh", None)


def ltv_linearize(system, p: SysIdParams) -> LinearizeFn:
    """The linearize hook of scheme ``p.scheme`` on ``system``'s black-box step, at every
    ``p.every``-th step and interpolated between (one-step schemes); with
    ``p.noise_floor`` > 0, entries below the difference quotients' resolution are zero
    (:func:`below_resolution`)."""
    scheme = get_scheme(p.scheme)
    linearize = sysid_knots.at_knots(scheme.make_linearize(system, p), p.every)
    if p.noise_floor == 0 or scheme.reduced:
        return linearize

    def floored(X, U, K, key):
        A, B = linearize(X, U, K, key)
        return below_resolution(A, B, X, p)

    return floored


def below_resolution(A: jax.Array, B: jax.Array, X: jax.Array, p: SysIdParams) -> tuple[jax.Array, jax.Array]:
    """Zero the entries of A [T, nx, nx], B [T, nx, nu] that a difference quotient of the
    black box cannot resolve: |entry| <= noise_floor * eps * max(|x_{t+1,i}|, 1) / sigma
    (row i; sigma_x for A, sigma_u for B), the round-off of the next state divided by the
    perturbation. An actuator that a force limit saturates moves nothing (its B column is
    exactly 0), but least squares returns round-off of about 1e-10 there; with a small R
    the Riccati gains divide by it (UR5e: |K| 291 at the last step, 1.4 for the oracle),
    and the closed loop under noise cost 20x the open loop."""
    eps = jnp.finfo(X.dtype).eps
    level = p.noise_floor * eps * jnp.maximum(jnp.abs(X[1:]), 1.0)[:, :, None]  # [T, nx, 1]
    A = jnp.where(jnp.abs(A) <= level / p.sigma_x, 0.0, A)
    B = jnp.where(jnp.abs(B) <= level / p.sigma_u, 0.0, B)
    return A, B


def fine_params(p: SysIdParams) -> SysIdParams | None:
    """The every-step identification a knotted one (``p.every`` > 1) hands over to near the
    optimum (:func:`mjx_surrogate.control.ilqr.ilqr`'s ``linearize_fine``); None when p.every = 1."""
    return p.replace(every=1) if p.every > 1 else None


def steps_per_identification(p: SysIdParams, T: int, nu: int = 0) -> int:
    """Control steps one identification of scheme ``p.scheme`` simulates on a horizon T
    (a reduced scheme's count depends on nu, the number of controls, too)."""
    scheme = get_scheme(p.scheme)
    identified = sysid_knots.identifications_per_iteration(T, p.every)
    if scheme.reduced:
        return scheme.simulated_steps(identified, p.n_samples, nu)
    return scheme.simulated_steps(identified, p.n_samples)


register_scheme(
    "central_difference",
    IdentificationScheme(
        lambda system, p: (
            lambda X, U, K, key: central_difference(
                system.step, X, U, key, p, _mesh(system), _limits(system, p)
            )
        ),
        lambda T, n: 2 * n * T,
        "D2C 2.0: one step from (x_t +- dx, u_t +- du) at every t",
        one_step=True,
        t_test=True,
    ),
)
register_scheme(
    "forward_difference",
    IdentificationScheme(
        lambda system, p: (
            lambda X, U, K, key: forward_difference(
                system.step, X, U, key, p, _mesh(system), _limits(system, p)
            )
        ),
        lambda T, n: (n + 1) * T,
        "one step from (x_t + dx, u_t + du) and from (x_t, u_t)",
        one_step=True,
        t_test=True,
    ),
)
register_scheme(
    "rollout",
    IdentificationScheme(
        lambda system, p: (
            lambda X, U, K, key: open_loop_rollouts(system.rollout, X, U, key, p, _mesh(system))
        ),
        lambda T, n: n * T,
        "the paper's: n open-loop perturbed rollouts",
        t_test=True,
    ),
)
register_scheme(
    "closed_loop",
    IdentificationScheme(
        lambda system, p: (
            lambda X, U, K, key: closed_loop_rollouts(system.step, X, U, K, key, p, _mesh(system))
        ),
        lambda T, n: n * T,
        "n perturbed rollouts under the current feedback gains",
        t_test=True,
    ),
)
