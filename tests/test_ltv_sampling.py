"""The analysis stage ``ltv`` (mjx_surrogate/analysis/ltv_sampling.py): each sampling distribution has
the stated moments, the LTV regression recovers a known system under each, and the two
rules on it turn when the numbers contradict the paper."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from experiments import report_rules
from mjx_surrogate.analysis import ltv_sampling
from mjx_surrogate.trajectory import simulate_batch


class Pendulumish:
    """x_{t+1} = x + dt [v, -sin(q) - 0.1 v + u]: a small nonlinear black box."""

    def step(self, x, u):
        q, v = x[..., 0], x[..., 1]
        return jnp.stack([q + 0.1 * v, v + 0.1 * (-jnp.sin(q) - 0.1 * v + u[..., 0])], -1)

    def rollout(self, x0, U):
        return simulate_batch(self.step, x0, U)


@pytest.mark.parametrize("kind", ltv_sampling.DISTRIBUTIONS)
def test_each_distribution_has_mean_zero_and_the_stated_std(kind):
    dx0, dU = ltv_sampling.perturbations(kind, jax.random.key(0), 300, 40, 2, 1, 0.01, 0.5, jnp.float64)
    assert dx0.shape == (300, 2) and dU.shape == (300, 40, 1)
    np.testing.assert_allclose(np.std(np.asarray(dx0), 0), 0.01, rtol=0.15)
    np.testing.assert_allclose(np.std(np.asarray(dU)), 0.5, rtol=0.02)
    assert abs(float(jnp.mean(dU))) < 0.02
    if kind == "uniform":
        assert float(jnp.max(jnp.abs(dU))) <= 0.5 * np.sqrt(3) + 1e-12
    if kind == "orthogonal":  # orthogonal columns across the rollouts, at t = 0 and after
        Z0 = np.concatenate([np.asarray(dx0) / 0.01, np.asarray(dU[:, 0]) / 0.5], -1)
        np.testing.assert_allclose(Z0.T @ Z0, 300 * np.eye(3), atol=1e-8)
        np.testing.assert_allclose(np.sum(np.asarray(dU[:, 5]) ** 2), 300 * 0.25, rtol=1e-12)


def test_the_regression_recovers_the_jacobians_under_every_distribution():
    sysm = Pendulumish()
    U = 0.3 * jnp.sin(jnp.arange(20.0))[:, None]
    X = simulate_batch(sysm.step, jnp.array([[2.0, 0.0]]), U[None])[0]
    m, arrays = ltv_sampling.measure(sysm, X, U, jax.random.key(1), 5, 12, 1e-2, 1e-2)
    rows = {k: v for k, v in m.items() if not k.startswith("_")}
    assert set(rows) == set(ltv_sampling.DISTRIBUTIONS)
    for v in rows.values():
        assert v["model_error_interval"][1] < 1e-2  # float32, sigma 1e-2: second-order error only
        assert 1 <= v["condition_unit_diagonal"] < 100 and v["condition_raw"] >= 1
        assert 0 < v["projection_spread"] < 1e-2
    assert arrays["ltv_model_error"].shape == (3, 5, 20)
    assert report_rules.ltv_distribution_claim(m) is True


def test_the_projection_spread_is_the_sindy_measure_on_the_regression():
    rng = np.random.default_rng(0)
    Z = rng.normal(size=(4, 3, 50, 2))
    W = np.array([[1.0], [2.0]])
    exact = np.einsum("ktni,ij->ktnj", Z, W)
    assert np.all(ltv_sampling.projection_spread(Z, exact) < 1e-12)  # no residual: no spread
    noisy = exact + 0.5 * rng.normal(size=exact.shape)
    assert np.all(ltv_sampling.projection_spread(Z, noisy) > 1e-2)


def _ltv(cond_hi=20.0, spread=1e-4, errors=(1e-4, 1.5e-4, 1.2e-4), error_hi=2e-4):
    return {
        k: {
            "model_error": e,
            "model_error_interval": [e / 2, error_hi],
            "condition_unit_diagonal": 10.0,
            "condition_unit_diagonal_interval": [5.0, cond_hi],
            "projection_spread": spread,
        }
        for k, e in zip(ltv_sampling.DISTRIBUTIONS, errors)
    } | {"_setup": {}}


ILL = {"SINDy cubic 5%": {"condition_unit_diagonal": 1e5}, "MLP 5%": {}}
VAR = {"SINDy cubic 5%": {"relative_to_rhs": 0.01}, "MLP 5%": {}}


def test_the_gram_rule_holds_on_the_papers_picture_and_fails_against_it():
    assert report_rules.ltv_gram_claim(_ltv(), ILL, VAR) is True
    assert report_rules.ltv_gram_claim(_ltv(cond_hi=500.0), ILL, VAR) is False  # above 100
    worse = {"SINDy cubic 5%": {"condition_unit_diagonal": 15.0}}
    assert report_rules.ltv_gram_claim(_ltv(), worse, VAR) is False  # SINDy better conditioned
    assert report_rules.ltv_gram_claim(_ltv(spread=0.05), ILL, VAR) is False  # more variance
    assert report_rules.ltv_gram_claim({}, ILL, VAR) is None
    old = {"SINDy cubic 5%": {"condition": 1e9}}  # a run from before the scaled condition
    assert report_rules.ltv_gram_claim(_ltv(), old, VAR) is None


def test_the_distribution_rule_fails_where_a_distribution_matters_or_the_model_is_off():
    assert report_rules.ltv_distribution_claim(_ltv()) is True
    assert report_rules.ltv_distribution_claim(_ltv(errors=(1e-4, 3e-4, 1e-4), error_hi=4e-4)) is False
    assert report_rules.ltv_distribution_claim(_ltv(error_hi=0.02)) is False  # one seed off by 2 %
    assert report_rules.ltv_distribution_claim({"_setup": {}}) is None


def test_the_orthogonal_design_is_left_out_and_said_so_below_nx_plus_nu_samples():
    sysm = Pendulumish()
    U = jnp.zeros((5, 1))
    X = simulate_batch(sysm.step, jnp.array([[0.5, 0.0]]), U[None])[0]
    m, _ = ltv_sampling.measure(sysm, X, U, jax.random.key(0), 2, 2, 1e-3, 1e-3)
    assert set(m) == {"gaussian", "uniform", "_setup"}
    assert m["_setup"]["left_out"] == ["orthogonal: needs n_samples >= nx + nu = 3"]
