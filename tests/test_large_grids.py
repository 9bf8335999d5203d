"""A grid of many cells: diagonal state weights, the reduced model's cost expansion by
Hessian-vector products, chunked batches, and the memory check, so that RO-D2C builds no
nx x nx array (a 256 x 256 grid in docs/pde.md)."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mjx_surrogate import sharding
from mjx_surrogate.control import d2c
from mjx_surrogate.control.ilqr import ILQRParams
from mjx_surrogate.control.local_model import projected_cost_derivatives, reduced_expansion
from mjx_surrogate.control.riccati import cost_derivatives
from mjx_surrogate.errors import ConfigError
from mjx_surrogate.identification import sysid_reduced
from mjx_surrogate.identification.sysid import SysIdParams
from mjx_surrogate.runs import memory
from mjx_surrogate.runs.config import Config, SysIdConfig, SystemConfig
from mjx_surrogate.systems import allen_cahn
from mjx_surrogate.tasks import at_step, make_task, task_cost


def _tasks(nx=6, nu=2, T=4, **kw):
    rng = np.random.default_rng(0)
    q, qf = rng.uniform(0.1, 2.0, nx), rng.uniform(0.1, 2.0, nx)
    args = (rng.normal(size=nx), rng.normal(size=nx))
    dense = make_task(*args, np.diag(q), np.diag(qf), np.eye(nu), T, **kw)
    diagonal = make_task(*args, q, qf, np.eye(nu), T, **kw)
    return dense, diagonal


@pytest.mark.parametrize("end", [None, 2])
def test_diagonal_weights_give_the_dense_costs_and_derivatives_bit_for_bit(end):
    """A weight held as its diagonal is the same cost as the diagonal matrix, to the bit: its
    value, and autodiff's derivatives (also for a task that ends within its horizon)."""
    dense, diagonal = _tasks(hinges=(1,))
    if end is not None:
        dense, diagonal = (at_step(t.replace(deadline=end), 0) for t in (dense, diagonal))
    rng = np.random.default_rng(1)
    X, U = jnp.asarray(rng.normal(size=(5, 6))), jnp.asarray(rng.normal(size=(4, 2)))
    for a, b in zip(cost_derivatives(task_cost(dense), X, U), cost_derivatives(task_cost(diagonal), X, U)):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    from mjx_surrogate.tasks import trajectory_cost

    assert float(trajectory_cost(dense, X, U)) == float(trajectory_cost(diagonal, X, U))


@pytest.mark.slow  # over 5 s: the fast tier's budget
@pytest.mark.parametrize("timed", [False, True])
def test_projected_derivatives_are_the_dense_ones_projected(timed):
    """V_t' l_xx V_t, l_ux V_t, ... by Hessian-vector products equal the projection of the
    dense derivatives (to round-off), for a non-diagonal weight, wrapped hinges and a task
    that ends within its horizon."""
    nx, nu, T, r = 7, 2, 5, 3
    rng = np.random.default_rng(2)
    M = rng.normal(size=(nx, nx))
    task = make_task(
        rng.normal(size=nx), rng.normal(size=nx), M @ M.T, np.eye(nx), np.eye(nu), T, hinges=(0, 3)
    )
    if timed:
        task = at_step(task.replace(deadline=3), 0)
    cost = task_cost(task)
    X, U = jnp.asarray(rng.normal(size=(T + 1, nx))), jnp.asarray(rng.normal(size=(T, nu)))
    V = jnp.asarray(np.linalg.qr(rng.normal(size=(T + 1, nx, r)))[0])
    want = reduced_expansion(cost_derivatives(cost, X, U), V)
    got = projected_cost_derivatives(cost, X, U, V)
    for a, b in zip(got, want):
        assert a.shape == b.shape
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-10, atol=1e-12)


def _square_shapes(jaxpr, n: int) -> list:
    """Shapes of every value in a jaxpr (its sub-jaxprs too) with two or more axes of size n."""
    found = []

    def check(values):
        for v in values:
            shape = getattr(getattr(v, "aval", None), "shape", ())
            if sum(d == n for d in shape) >= 2:
                found.append(shape)

    def walk(j):
        j = getattr(j, "jaxpr", j)
        check(list(j.invars) + list(j.constvars))
        for eqn in j.eqns:
            check(eqn.outvars)
            for p in eqn.params.values():
                for sub in p if isinstance(p, (tuple, list)) else (p,):
                    if hasattr(sub, "eqns") or hasattr(getattr(sub, "jaxpr", None), "eqns"):
                        walk(sub)

    walk(jaxpr)
    return found


def test_a_reduced_solve_with_diagonal_weights_builds_no_nx_by_nx_array():
    """The whole RO-D2C solve on a 16 x 16 grid (nx = 256) traced: no value has two axes of
    size nx. With the full-order scheme, or the weights as matrices, there are such values
    (the walk finds what it looks for)."""
    s = allen_cahn.make_system(16, dims=2)
    fields = allen_cahn.grow_fields(s.nx, s.nu, T=6)
    task = make_task(**fields, u_min=s.u_min, u_max=s.u_max)
    U0, key, p = jnp.zeros((6, s.nu)), jax.random.key(0), ILQRParams(max_iter=2)

    def shapes(task, sysid):
        jaxpr = jax.make_jaxpr(lambda U0: d2c.solve_d2c(s, task, U0, key, p, sysid))(U0)
        return _square_shapes(jaxpr, s.nx)

    reduced = SysIdParams(scheme="reduced", n_samples=8)
    assert shapes(task, reduced) == []
    dense = task.replace(Q=jnp.diag(task.Q), Q_f=jnp.diag(task.Q_f))
    assert shapes(dense, reduced) != []
    assert shapes(task, SysIdParams(n_samples=s.nx + s.nu)) != []


@pytest.mark.slow  # over 5 s: the fast tier's budget
def test_the_reduced_identification_in_chunks_is_the_batched_one(monkeypatch):
    """The one-step samples run a few time steps at a time where a batch is large; the
    model is the one of the whole batch at once (round-off)."""
    s = allen_cahn.make_system(16, dims=2)
    task = make_task(**allen_cahn.grow_fields(s.nx, s.nu, T=6), u_min=s.u_min, u_max=s.u_max)
    U = 0.5 * jnp.ones((6, s.nu))
    X = s.rollout(task.x0[None], U[None])[0]
    p = SysIdParams(scheme="reduced", n_samples=8)
    whole = sysid_reduced.reduced_central_difference(s, X, U, jax.random.key(3), p)
    monkeypatch.setattr(sharding, "CHUNK_NUMBERS", 2 * (8 + s.nu) * s.nx * 2)  # two time steps a chunk
    chunked = sysid_reduced.reduced_central_difference(s, X, U, jax.random.key(3), p)
    for a, b in zip(chunked, whole):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-9, atol=1e-12)


def test_the_memory_check_names_the_longest_horizon_that_fits(monkeypatch):
    """On a machine of 256 MiB the reduced scheme on a 64 x 64 grid at T = 50 does not fit:
    refused on task.T, naming the longest horizon whose arrays do fit (and the next does
    not); the full-order scheme does not fit even at T = 1: refused on system.name."""
    monkeypatch.setattr(memory, "machine_memory", lambda: 2**28)
    s = allen_cahn.make_system(64, dims=2)
    task = make_task(**allen_cahn.grow_fields(s.nx, s.nu, T=50), u_min=s.u_min, u_max=s.u_max)
    cfg = Config(system=SystemConfig(name="allen_cahn2d64"), sysid=SysIdConfig(scheme="reduced"))
    with pytest.raises(ConfigError) as e:
        memory.check_solve_memory(cfg, s, task, 32, oracle=False)
    assert e.value.field == "task.T"
    t_max = int(str(e.value).split("T <= ")[1].split()[0])
    fits = lambda T: memory.solve_bytes(task, s.nx, s.nu, T, False, 32) <= 2**28  # noqa: E731
    assert fits(t_max) and not fits(t_max + 1)
    full = dataclasses.replace(cfg, sysid=SysIdConfig())
    with pytest.raises(ConfigError) as e:
        memory.check_solve_memory(full, s, task, s.nx + s.nu, oracle=False)
    assert e.value.field == "system.name" and "T = 1" in str(e.value)


def test_vmap_in_chunks_maps_sequential_chunks_only_where_a_batch_is_large():
    """Over the budget: a loop over chunks (uneven last chunk included), the vmap's values;
    within it: the plain vmap, no loop."""
    f = lambda x: jnp.sin(x) * x.sum()  # noqa: E731
    xs = jnp.arange(70.0).reshape(7, 10)
    prims = lambda n: {
        e.primitive.name for e in jax.make_jaxpr(lambda x: sharding.vmap_in_chunks(f, x, n))(xs).eqns
    }  # noqa: E731
    assert "scan" in prims(sharding.CHUNK_NUMBERS // 3) and "scan" not in prims(10)
    np.testing.assert_array_equal(
        sharding.vmap_in_chunks(f, xs, sharding.CHUNK_NUMBERS // 3), jax.vmap(f)(xs)
    )
