"""Pipeline steps: the simulation count of a D2C solve against a counting black box."""

import types

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mjx_surrogate.control.ilqr import Cost, ILQRParams, ilqr
from mjx_surrogate.identification import sysid
from mjx_surrogate.runs import pipeline

A = np.array([[1.0, 0.1], [-0.3, 1.0]])
B = np.array([[0.0], [0.1]])


CASES = [("central_difference", 0, 1), ("forward_difference", 0, 1), ("forward_difference", 3, 1)]


@pytest.mark.slow
@pytest.mark.parametrize("scheme, reuse, every", CASES + [("central_difference", 0, 4)])
def test_simulation_curve_counts_every_black_box_step(scheme, reuse, every):
    calls = {"n": 0}

    def host_step(x, u):
        calls["n"] += int(np.prod(x.shape[:-1]))  # a batch of one-step simulations
        return np.einsum("ij,...j->...i", A, x) + np.einsum("ij,...j->...i", B, u)

    def step(x, u):
        out = jax.ShapeDtypeStruct(x.shape, x.dtype)
        return jax.pure_callback(host_step, out, x, u, vmap_method="broadcast_all")

    T, n_alphas = 15, 4
    p = sysid.SysIdParams(sigma_x=1e-4, sigma_u=1e-4, scheme=scheme, n_samples=6, every=every)
    linearize = sysid.ltv_linearize(types.SimpleNamespace(step=step), p)
    fine = sysid.ltv_linearize(types.SimpleNamespace(step=step), p.replace(every=1)) if every > 1 else None
    cost = Cost(lambda x, u: 0.5 * x @ x + 0.05 * u @ u, lambda x: 5.0 * x @ x)
    params = ILQRParams(
        max_iter=12,
        n_alphas=n_alphas,
        rel_tol=0.0,
        k_tol=0.0,
        reuse_tol=0.5,
        reuse_max=reuse,
        refine_tol=0.05,
    )
    inf = jnp.full(1, jnp.inf)
    res = ilqr(
        step,
        linearize,
        cost,
        jnp.array([1.0, 0.0]),
        jnp.zeros((T, 1)),
        -inf,
        inf,
        params,
        jax.random.key(0),
        linearize_fine=fine,
    )
    it = int(res.iterations)
    h = np.asarray(res.cost_history)[: it + 1]
    ident = np.asarray(res.identified)[:it]
    assert it >= 5 and not ident.all()  # iterations without an identification (rejected, reused)
    assert ident.any() and (np.any(h[1:] == h[:-1]) or reuse)
    if every > 1:  # the coarse model hands over to the fine one
        assert set(ident[ident > 0].tolist()) == {1, 2}
    per_id = pipeline.steps_per_identification(p, T)
    curve = pipeline.simulation_curve(res.identified, it, T, n_alphas, *per_id)
    assert curve.shape == (it + 1,) and curve[0] == T
    assert curve[-1] == calls["n"]
    m = pipeline.simulation_metrics(res, T, n_alphas, p)
    assert m["simulated_steps"] == calls["n"]
    first = np.nonzero(h <= h[-1] * 1.01)[0][0]
    assert m["simulations_to_optimum"]["1%"] == curve[first]
    assert m["simulations_to_optimum"]["1%"] <= m["simulations_to_optimum"]["0.1%"] <= calls["n"]
