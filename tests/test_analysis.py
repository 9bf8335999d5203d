"""Analyses: exact moments and Gram matrices, Monte Carlo within sampling error, the MLP
parameter-Jacobian Gram against finite differences, error projections."""

from fractions import Fraction

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from flax import nnx
from jax.flatten_util import ravel_pytree

from mjx_surrogate.analysis import spectra
from mjx_surrogate.analysis import theory as th
from mjx_surrogate.surrogates import mlp


def test_gaussian_monomial_gram_is_the_hankel_matrix_of_moments():
    s = Fraction(1, 2)
    G = th.gram_exact("monomial", 4, "gauss", s)
    for k in range(5):
        for l in range(5):
            m = k + l
            want = 0 if m % 2 else th.double_factorial(m - 1) * s**m
            assert G[k][l] == want
    # cond of the exact matrix against float64 eigenvalues where float64 is reliable
    Gf = np.array(G, float)
    w = np.linalg.eigvalsh(Gf)
    assert th.condition_number(G) == pytest.approx(w[-1] / w[0], rel=1e-9)
    # Var[x^(2N)] = (4N-1)!! - ((2N-1)!!)^2 sigma^(4N): the paper's monomial formula
    for N in range(1, 5):
        assert float(th.entry_variance("monomial", N, N, "gauss", s)) == pytest.approx(
            th.paper_monomial_variance(N, 0.5), rel=1e-12
        )


@pytest.mark.parametrize("basis,dist", [("hermite", "gauss"), ("legendre", "uniform")])
def test_orthonormal_bases_have_identity_gram(basis, dist):
    G = th.gram_exact(basis, 6, dist, Fraction(3, 2))
    np.testing.assert_allclose(np.array(G, float), np.eye(7), atol=1e-14)
    assert th.condition_number(G) == pytest.approx(1.0)


@pytest.mark.parametrize(
    "basis,dist,n", [("monomial", "gauss", 2), ("hermite", "gauss", 3), ("legendre", "uniform", 4)]
)
def test_monte_carlo_matches_the_closed_form_within_sampling_error(basis, dist, n):
    rng = np.random.default_rng(0)
    R, trials = 4000, 400
    G = th.monte_carlo_gram(basis, n, dist, 1.0, R, trials, rng)
    exact = np.array(th.gram_exact(basis, n, dist, 1), float)
    var = float(th.entry_variance(basis, n, n, dist, 1))
    # mean of G^R_NN over trials: unbiased, std sqrt(var / (R trials))
    assert abs(G[:, n, n].mean() - exact[n, n]) < 5 * np.sqrt(var / (R * trials))
    # R x sample variance of G^R_NN estimates sigma_NN^2 (heavier tails: looser bound)
    assert G[:, n, n].var(ddof=1) * R == pytest.approx(var, rel=0.35)


def test_paper_formulas_disagree_where_the_exact_numbers_say_so():
    exact = [float(th.entry_variance("legendre", n, n, "uniform", 1)) for n in range(1, 9)]
    paper = [th.paper_legendre_samples(n, 1.0) for n in range(1, 9)]
    assert exact[-1] / exact[0] < 3  # slow growth
    assert paper[-1] / paper[0] > 1e4  # the printed formula explodes
    her = [float(th.entry_variance("hermite", n, n, "gauss", 1)) for n in range(1, 6)]
    assert her == [2, 14, 92, 638, 4652]  # E[He_n^4]/(n!)^2 - 1


def test_mlp_jacobian_gram_matches_finite_differences():
    spec = mlp.MLPSpec(widths=(3,), batch_size=4, epochs=1)
    z = jax.random.normal(jax.random.key(0), (8, 2))
    y = jax.random.normal(jax.random.key(1), (8, 2))
    model = mlp.train(spec, jax.random.key(2), z, y, z, y).model
    zs, ys = spectra.standardise(model, z, y)
    H = np.asarray(spectra.mlp_jacobian(model, zs))
    flat, unravel = ravel_pytree(model.params)
    h = lambda th_: np.asarray(nnx.merge(model.graphdef, unravel(th_))(zs), np.float64).ravel()  # noqa
    eps = 1e-3
    fd = np.stack(
        [(h(flat.at[i].add(eps)) - h(flat.at[i].add(-eps))) / (2 * eps) for i in range(flat.shape[0])], axis=1
    )
    np.testing.assert_allclose(H, fd, atol=2e-3)
    G = np.asarray(spectra.mlp_gram(model, zs))  # evaluated at the same parameters in float64
    H64 = np.asarray(spectra.mlp_jacobian(model, zs, evaluate_in=jnp.float64))
    np.testing.assert_allclose(H64, H, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(G, H64.T @ H64 / 8, rtol=1e-10, atol=1e-12)
    d = np.asarray(spectra.mlp_descent_direction(model, zs, ys))
    loss = lambda th_: np.mean((h(th_) - np.asarray(ys, np.float64).ravel()) ** 2)  # noqa
    g = np.array(
        [(loss(flat.at[i].add(eps)) - loss(flat.at[i].add(-eps))) / (2 * eps) for i in range(flat.shape[0])]
    )
    # (1/R) H' Delta = -(R nx / (2 R)) dL/dtheta with L the mean over R nx entries
    np.testing.assert_allclose(d, -g * (8 * 2) / (2 * 8), atol=2e-3)


def test_error_projections_vanish_for_the_own_fit_and_spread_across_sets():
    rng = np.random.default_rng(4)
    thetas = [jnp.asarray(rng.normal(size=(200, 4))) for _ in range(3)]
    ys = [t @ jnp.ones((4, 1)) + 0.1 * jnp.asarray(rng.normal(size=(200, 1))) for t in thetas]
    own = jnp.linalg.lstsq(thetas[0], ys[0])[0]
    np.testing.assert_allclose(spectra.error_projections(thetas[:1], ys[:1], own), 0, atol=1e-12)
    pooled = jnp.linalg.lstsq(jnp.concatenate(thetas), jnp.concatenate(ys))[0]
    D = np.asarray(spectra.error_projections(thetas, ys, pooled))
    assert D.shape == (3, 4, 1) and np.abs(D).max() > 1e-4
    cos = spectra.cosine_matrix(np.eye(3))
    np.testing.assert_allclose(cos, np.eye(3))


def test_a_relu_mlps_gram_is_singular_by_its_symmetries_and_the_rest_is_judged_apart():
    """Each ReLU hidden unit's scaling (w_in, b) -> c (w_in, b), w_out -> w_out / c leaves the
    network unchanged: one exact null direction of the Jacobian Gram per unit, with more
    data than parameters. The whole Gram's condition number is then no evidence of
    ill-conditioning; the spectrum apart from that null space is (float64 NumPy reference)."""
    from experiments import report

    spec = mlp.MLPSpec(widths=(5,), batch_size=16, epochs=2)
    z = jax.random.normal(jax.random.key(0), (64, 2))
    y = jnp.sin(z)
    model = mlp.train(spec, jax.random.key(2), z, y, z, y).model
    zs, _ = spectra.standardise(model, z, y)
    H = np.asarray(spectra.mlp_jacobian(model, zs), np.float64)  # [64 * 2, 27]
    assert H.shape == (128, 27)
    H = np.asarray(spectra.mlp_jacobian(model, zs, evaluate_in=jnp.float64))  # as mlp_gram takes it
    eig = spectra.eigenvalues(spectra.mlp_gram(model, zs))
    rank, cond = spectra.rank_and_condition(eig, spectra.gram_rank_tolerance(*H.shape, np.float64))
    assert rank == np.linalg.matrix_rank(H) == 27 - 5  # one null direction per hidden unit, no more
    sv = np.linalg.svd(H, compute_uv=False)
    np.testing.assert_allclose(cond, sv[0] ** 2 / sv[rank - 1] ** 2, rtol=1e-6)
    assert np.isfinite(cond) and spectra.condition(eig) > 1e15  # whole: singular to rounding
    # the rule on the whole Gram holds whatever the network; on the rest it can fail
    row = {"condition": spectra.condition(eig), "condition_of_the_rest": cond}
    assert report._ill_conditioned({"MLP": row}) is True
    assert report._ill_conditioned({"MLP": row}, "condition_of_the_rest") is (cond > 1e6)
    assert (
        report._ill_conditioned({"MLP": row | {"condition_of_the_rest": 50.0}}, "condition_of_the_rest")
        is False
    )
    assert report._ill_conditioned({"MLP": {"condition": 1e9}}, "condition_of_the_rest") is None  # not kept
