"""SINDy-style least squares: recovery of known maps, pysindy as the oracle, Gram matrix."""

import warnings
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mjx_surrogate.surrogates import library, sindy
from mjx_surrogate.surrogates.library import LibrarySpec


def _pysindy_names(lib, nz):
    lib.fit(np.zeros((2, nz)))
    return lib.get_feature_names()


def test_library_columns_match_pysindy_names_and_values():
    ps = pytest.importorskip("pysindy")
    rng = np.random.default_rng(0)
    z = rng.normal(size=(50, 3))
    spec = LibrarySpec(degree=3, trig_coords=(0, 1, 2))
    ref_lib = ps.PolynomialLibrary(degree=3) + ps.FourierLibrary(n_frequencies=1)
    ref_lib.fit(z)
    assert library.names(spec, 3) == ref_lib.get_feature_names()
    np.testing.assert_allclose(
        library.features(spec, jnp.asarray(z)), ref_lib.transform(z), rtol=1e-12, atol=1e-12
    )
    pure = LibrarySpec(degree=4, cross_terms=False)
    ref_pure = ps.PolynomialLibrary(degree=4, include_interaction=False)
    assert library.names(pure, 3) == _pysindy_names(ref_pure, 3)
    assert library.size(spec, 3) == 20 + 6


def _numpy_columns(spec: LibrarySpec, z: np.ndarray) -> np.ndarray:
    """Theta(z) column by column in float64 NumPy, from the library's own column list."""
    monos = [
        np.prod(z[:, list(t)], axis=1) if t else np.ones(len(z)) for t in library._monomials(spec, z.shape[1])
    ]
    trig = [getattr(np, fn)(h * z[:, j]) for fn, h, j in library._trig_terms(spec)]
    prods = [m * t for m in monos[int(spec.bias) :] for t in trig] if spec.products else []
    return np.stack(monos + trig + prods, axis=1)


@pytest.mark.parametrize(
    "spec",
    [
        LibrarySpec(degree=4, trig_coords=(0, 2), harmonics=2, products=True),
        LibrarySpec(degree=3, cross_terms=False, bias=False, trig_coords=(1,), products=True),
        LibrarySpec(degree=0, bias=False, trig_coords=(0, 1), harmonics=3),
        LibrarySpec(degree=1),
    ],
)
def test_features_equal_the_column_by_column_evaluation(spec):
    z = np.random.default_rng(2).normal(size=(30, 4))
    np.testing.assert_allclose(
        library.features(spec, jnp.asarray(z)), _numpy_columns(spec, z), rtol=1e-14, atol=0
    )
    zb = jnp.asarray(z.reshape(5, 6, 4))  # leading batch axes
    assert library.features(spec, zb).shape == (5, 6, library.size(spec, 4))


def test_the_traced_library_does_not_grow_with_its_size():
    """One gather per degree and term, not one per column: the Jacobians iLQR takes of a
    fish-sized quadratic library (561 columns) trace to as many operations as those of an
    8-variable one (45 columns)."""

    def n_ops(nz):
        spec = LibrarySpec(degree=2, trig_coords=(0, 1), products=True)
        return len(jax.make_jaxpr(jax.jacfwd(partial(library.features, spec)))(jnp.ones(nz)).eqns)

    assert n_ops(32) == n_ops(8)


def test_recovers_a_polynomial_map_to_round_off():
    rng = np.random.default_rng(1)
    x = rng.uniform(-1, 1, size=(400, 2))
    u = rng.uniform(-1, 1, size=(400, 1))
    spec = LibrarySpec(degree=3)
    P = library.size(spec, 3)
    C = rng.normal(size=(P, 2)) * (rng.random((P, 2)) < 0.4)
    xn = np.asarray(sindy.design(spec, jnp.asarray(x), jnp.asarray(u))) @ C
    for method in ("svd", "normal"):
        m = sindy.fit(spec, jnp.asarray(x), jnp.asarray(u), jnp.asarray(xn), method=method)
        np.testing.assert_allclose(m.coef, C, atol=1e-8)
    inc = sindy.fit(spec, jnp.asarray(x), jnp.asarray(u), jnp.asarray(x + xn), increment=True)
    np.testing.assert_allclose(inc.coef, C, atol=1e-8)
    np.testing.assert_allclose(inc.step(jnp.asarray(x[:5]), jnp.asarray(u[:5])), (x + xn)[:5], atol=1e-8)


def _trajectories(rng, n=20, T=40):
    """A noisy nonlinear discrete map with a control input, as trajectories."""
    xs, us = [], []
    for _ in range(n):
        x = np.zeros((T + 1, 2))
        x[0] = rng.uniform(-1, 1, 2)
        u = rng.uniform(-1, 1, (T, 1))
        for t in range(T):
            a, b = x[t]
            x[t + 1] = [
                0.9 * a + 0.1 * np.sin(b) + 0.2 * u[t, 0],
                0.8 * b - 0.3 * a * a + 0.05 * np.cos(a) + 0.01 * rng.normal(),
            ]
        xs.append(x)
        us.append(u)
    return xs, us


@pytest.mark.parametrize("threshold,normalize", [(0.0, False), (0.02, False), (0.05, True)])
def test_matches_pysindy_discrete_sindy(threshold, normalize):
    ps = pytest.importorskip("pysindy")
    rng = np.random.default_rng(2)
    xs, us = _trajectories(rng)
    spec = LibrarySpec(degree=2, trig_coords=(0, 1, 2))
    lib = ps.PolynomialLibrary(degree=2) + ps.FourierLibrary(n_frequencies=1)
    alpha = 0.05
    opt = ps.STLSQ(threshold=threshold, alpha=alpha, normalize_columns=normalize, max_iter=50)
    model = ps.DiscreteSINDy(optimizer=opt, feature_library=lib)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model.fit([a[:-1] for a in xs], 1.0, x_next=[a[1:] for a in xs], u=us)
    ref = model.coefficients().T  # [P, nx]
    assert model.get_feature_names() == library.names(spec, 3, ["x0", "x1", "u0"])
    x = jnp.asarray(np.concatenate([a[:-1] for a in xs]))
    xn = jnp.asarray(np.concatenate([a[1:] for a in xs]))
    u = jnp.asarray(np.concatenate(us))
    theta = sindy.design(spec, x, u)
    if threshold == 0.0:
        coef = sindy.lstsq(theta, xn)
        # pysindy's STLSQ with threshold 0 is ridge-free least squares after unbiasing
    else:
        coef = sindy.stlsq(theta, xn, threshold, alpha, 50, normalize_columns=normalize)
    np.testing.assert_array_equal(np.asarray(coef) != 0, ref != 0)
    np.testing.assert_allclose(coef, ref, rtol=1e-7, atol=1e-9)
    if threshold > 0:
        assert 0 < np.count_nonzero(ref) < ref.size  # the case really is sparse


def test_gram_and_projections_are_the_normal_equations():
    rng = np.random.default_rng(3)
    theta = jnp.asarray(rng.normal(size=(300, 7)))
    y = jnp.asarray(rng.normal(size=(300, 2)))
    G, b = sindy.gram(theta), sindy.projections(theta, y)
    np.testing.assert_allclose(G, np.asarray(theta).T @ np.asarray(theta) / 300, rtol=1e-12)
    c = sindy.lstsq(theta, y)
    np.testing.assert_allclose(np.asarray(G) @ np.asarray(c), b, atol=1e-12)
    ref = np.linalg.lstsq(np.asarray(theta), np.asarray(y), rcond=None)[0]
    np.testing.assert_allclose(c, ref, atol=1e-12)
