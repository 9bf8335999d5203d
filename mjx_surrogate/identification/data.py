"""Data sets sampled around an optimal trajectory (the paper's "Sampling distributions").

Given the optimum (X* [T+1, nx], U* [T, nu]) of a task, a data set is N trajectories of
the black box driven by perturbed controls

    u_t^i = u_t* + level * U_max * w_t^i,   w_t^i ~ N(0, I),
    x_0^i = x_0* + x0_sigma * v^i,          v^i ~ N(0, I),

where U_max [nu] is the actuator limit max(|u_min|, |u_max|) of a channel whose limits are
finite, else the largest |u_t*| of that channel over the horizon (a channel with u* = 0
everywhere gets U_max = 1 so that its level still means something). Perturbed controls
are clipped to the limits, so a data set holds the controls the black box applied. The
paper quotes levels as percentages of U_max (5 ... 100 %); here ``level`` is the fraction.
All N trajectories come from one batched black-box rollout. Trajectories, not
transitions, are split train : test, so no test transition is a neighbour in time of a
training one.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from mjx_surrogate.identification.rollout import rollout
from mjx_surrogate.systems.black_box import BlackBox
from mjx_surrogate.systems.system_jit import system_jit


class Dataset(NamedTuple):
    """Perturbed trajectories around a nominal; the leading axis is the trajectory."""

    X: jax.Array  # [N, T+1, nx] black-box states (NaN after a blow-up)
    U: jax.Array  # [N, T, nu] applied controls


class Transitions(NamedTuple):
    """One-step regression data, flattened over trajectories and time."""

    x: jax.Array  # [M, nx]
    u: jax.Array  # [M, nu]
    x_next: jax.Array  # [M, nx]


@jax.jit
def u_max(U_star: jax.Array, lo: jax.Array | None = None, hi: jax.Array | None = None) -> jax.Array:
    """U_max [nu]: the actuator limit max(|lo|, |hi|) where both are finite, else the
    largest |u*| per channel over the horizon (1 where u* is all zero)."""
    m = jnp.max(jnp.abs(U_star), axis=0)
    m = jnp.where(m > 0, m, jnp.ones_like(m))
    if lo is None or hi is None:
        return m
    limit = jnp.maximum(jnp.abs(lo), jnp.abs(hi))
    return jnp.where(jnp.isfinite(lo) & jnp.isfinite(hi) & (limit > 0), limit, m)


@system_jit(static_argnames=("system", "n_traj"))
def sample(
    system: BlackBox,
    X_star: jax.Array,
    U_star: jax.Array,
    key: jax.Array,
    n_traj: int,
    level: float,
    x0_sigma: float = 0.0,
    lo: jax.Array | None = None,
    hi: jax.Array | None = None,
) -> Dataset:
    """N perturbed trajectories of the black box around (X*, U*) in one batched rollout.

    X_star [T+1, nx], U_star [T, nu], level: control noise as a fraction of U_max;
    lo, hi [nu]: the task's control limits (None or infinite: none).
    """
    k_u, k_x = jax.random.split(key)
    T, nu = U_star.shape
    scale = level * u_max(U_star, lo, hi)
    U = U_star + scale * jax.random.normal(k_u, (n_traj, T, nu), U_star.dtype)
    if lo is not None and hi is not None:
        U = jnp.clip(U, lo, hi)
    x0 = X_star[0] + x0_sigma * jax.random.normal(k_x, (n_traj, X_star.shape[-1]), X_star.dtype)
    return Dataset(rollout(system, x0, U), U)


def sample_seeds(
    system: BlackBox,
    X_star: jax.Array,
    U_star: jax.Array,
    keys: jax.Array,
    n_traj: int,
    level: float,
    x0_sigma: float = 0.0,
    lo: jax.Array | None = None,
    hi: jax.Array | None = None,
) -> Dataset:
    """Data sets from one sampling distribution, one per key: X [S, N, T+1, nx]."""
    return jax.vmap(lambda k: sample(system, X_star, U_star, k, n_traj, level, x0_sigma, lo, hi))(keys)


def split(data: Dataset, key: jax.Array, test_fraction: float = 0.1) -> tuple[Dataset, Dataset]:
    """Random train : test split by trajectory (paper: 9 : 1)."""
    n = data.X.shape[0]
    n_test = max(1, int(round(test_fraction * n)))
    if n_test >= n:
        raise ValueError(f"test_fraction={test_fraction} leaves no training trajectory of {n}")
    return _split(data, key, n_test)


@functools.partial(jax.jit, static_argnums=2)
def _split(data: Dataset, key: jax.Array, n_test: int) -> tuple[Dataset, Dataset]:
    # one program: eager, the permutation and each take would compile on their own
    perm = jax.random.permutation(key, data.X.shape[0])
    test, train = perm[:n_test], perm[n_test:]
    take = lambda idx: Dataset(data.X[idx], data.U[idx])  # noqa: E731
    return take(train), take(test)


def finite_trajectories(data: Dataset) -> Dataset:
    """The trajectories of ``data`` with every state finite, as NumPy (picked on the host:
    how many are kept depends on the data)."""
    X = np.asarray(data.X)
    ok = np.isfinite(X).all((1, 2))
    return Dataset(X[ok], np.asarray(data.U)[ok])


def transitions(data: Dataset) -> Transitions:
    """Flatten [N, T, ...] into M = N*T transitions, dropping any with a non-finite entry.

    Runs eagerly (the number kept depends on the data): one program flattens and tests,
    and only data with a non-finite entry are then indexed.
    """
    x, u, xn, ok = _flat_transitions(data)
    ok = np.asarray(ok)
    if ok.all():
        return Transitions(x, u, xn)
    keep = np.flatnonzero(ok)
    return Transitions(x[keep], u[keep], xn[keep])


@jax.jit
def _flat_transitions(data: Dataset) -> tuple[jax.Array, jax.Array, jax.Array, jax.Array]:
    nx, nu = data.X.shape[-1], data.U.shape[-1]
    x = data.X[:, :-1].reshape(-1, nx)
    xn = data.X[:, 1:].reshape(-1, nx)
    u = data.U.reshape(-1, nu)
    ok = jnp.isfinite(x).all(-1) & jnp.isfinite(xn).all(-1) & jnp.isfinite(u).all(-1)
    return x, u, xn, ok
