"""The one-step model interface: exact model, LTV from data, surrogates, evaluation."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mjx_surrogate.analysis import evaluation
from mjx_surrogate.analysis.evaluation import prediction_errors
from mjx_surrogate.identification import data, step_models
from mjx_surrogate.identification.rollout import rollout
from mjx_surrogate.surrogates import sindy
from mjx_surrogate.surrogates.library import LibrarySpec


# MJX on the pendulum: the wrappers are the same on every backend, and MJX's cartpole
# programs take about 9 s each to compile
@pytest.mark.slow
@pytest.mark.parametrize("name,backend", [("pendulum", "mjx"), ("cartpole", "native")])
def test_exact_model_reproduces_the_black_box(systems, name, backend):
    sys_ = systems(name, backend)
    key = jax.random.key(0)
    x0 = jnp.zeros((5, sys_.nx)).at[:, sys_.nx // 2 - 1].set(jnp.linspace(2.5, 3.1, 5))  # angles near upright
    U = 0.3 * jax.random.normal(key, (5, 12, 1))
    np.testing.assert_allclose(
        step_models.predict(step_models.black_box(sys_), x0, U), rollout(sys_, x0, U), atol=1e-12
    )
    X = rollout(sys_, x0, U)
    np.testing.assert_allclose(step_models.one_step(step_models.black_box(sys_), X, U), X[:, 1:], atol=1e-12)


def test_ltv_model_from_data_recovers_a_linear_time_varying_system():
    rng = np.random.default_rng(0)
    T, nx, nu, n = 6, 3, 2, 40
    A = rng.normal(size=(T, nx, nx)) * 0.5
    B = rng.normal(size=(T, nx, nu))
    Xn = np.zeros((T + 1, nx))
    Un = rng.normal(size=(T, nu))
    for t in range(T):
        Xn[t + 1] = A[t] @ Xn[t] + B[t] @ Un[t] + 0.1
    X = np.zeros((n, T + 1, nx))
    U = Un + rng.normal(size=(n, T, nu))
    X[:, 0] = rng.normal(size=(n, nx))
    for t in range(T):
        X[:, t + 1] = X[:, t] @ A[t].T + U[:, t] @ B[t].T + 0.1
    ltv = step_models.fit_ltv(data.Dataset(jnp.asarray(X), jnp.asarray(U)), jnp.asarray(Xn), jnp.asarray(Un))
    np.testing.assert_allclose(ltv.A, A, atol=1e-10)
    np.testing.assert_allclose(ltv.B, B, atol=1e-10)
    pred = step_models.predict(ltv.step_t, jnp.asarray(X[:, 0]), jnp.asarray(U))
    np.testing.assert_allclose(pred, X, atol=1e-9)
    pred = step_models.predict(ltv.as_pytree(), jnp.asarray(X[:, 0]), jnp.asarray(U))
    np.testing.assert_allclose(pred, X, atol=1e-9)


def test_prediction_errors_of_an_exact_surrogate_are_zero_and_divergence_is_reported():
    rng = np.random.default_rng(1)
    spec = LibrarySpec(degree=2)
    C = np.zeros((10, 2))
    C[1, 0], C[2, 1], C[3, 0] = 0.9, 0.8, 0.1  # x0' = 0.9 x0 + 0.1 u, x1' = 0.8 x1
    model = sindy.SindyModel(jnp.asarray(C), spec, False)
    X0 = jnp.asarray(rng.normal(size=(8, 2)))
    U = jnp.asarray(rng.normal(size=(8, 10, 1)))
    X = step_models.predict(step_models.time_invariant(model.step), X0, U)
    m, _ = prediction_errors(step_models.time_invariant(model.step), data.Dataset(X, U))
    assert m["one_step_rmse"] < 1e-14 and m["multi_step_rmse"] < 1e-14 and m["diverged"] == 0
    assert prediction_errors(step_models.as_pytree(model), data.Dataset(X, U))[0] == m
    C2 = C.copy()
    C2[7, 1] = 50.0  # x1' gains 50 x1^2: blows up
    bad = sindy.SindyModel(jnp.asarray(C2), spec, False)
    n = evaluation._predictions._cache_size()
    m2, _ = prediction_errors(step_models.as_pytree(bad), data.Dataset(X, U))
    assert m2["diverged"] > 0 and m2["multi_step_rmse"] is None
    assert evaluation._predictions._cache_size() == n  # another fit, the same program
