"""Data sets around a nominal: distribution, determinism, split, transitions."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mjx_surrogate.identification import data
from mjx_surrogate.identification.rollout import rollout


@pytest.mark.slow
def test_u_max_and_perturbation_statistics(systems):
    sys_ = systems("pendulum")
    T = 8
    U_star = jnp.linspace(-0.5, 0.3, T)[:, None]
    X_star = rollout(sys_, jnp.array([[np.pi, 0.0]]), U_star[None])[0]
    assert float(data.u_max(U_star)[0]) == pytest.approx(0.5)
    assert float(data.u_max(jnp.zeros((T, 1)))[0]) == 1.0  # an all-zero channel
    ds = data.sample(sys_, X_star, U_star, jax.random.key(0), 4000, 0.2)
    dU = np.asarray(ds.U - U_star)
    # std of the control noise = level * U_max, mean 0 (sampling error ~ 1/sqrt(32000))
    assert dU.std() == pytest.approx(0.2 * 0.5, rel=0.02)
    assert abs(dU.mean()) < 0.003
    # states are the black box's response to those controls
    np.testing.assert_allclose(ds.X, rollout(sys_, ds.X[:, 0], ds.U), atol=1e-12)
    np.testing.assert_allclose(ds.X[:, 0], np.broadcast_to(X_star[0], ds.X[:, 0].shape))
    again = data.sample(sys_, X_star, U_star, jax.random.key(0), 4000, 0.2)
    np.testing.assert_array_equal(ds.U, again.U)


@pytest.mark.slow  # over 5 s: the fast tier's budget
def test_u_max_is_the_actuator_limit_and_data_hold_the_applied_controls(systems):
    sys_ = systems("pendulum")
    T = 8
    U_star = jnp.linspace(-0.5, 0.3, T)[:, None]
    X_star = rollout(sys_, jnp.array([[np.pi, 0.0]]), U_star[None])[0]
    lo, hi = jnp.array([-2.0]), jnp.array([1.0])
    assert float(data.u_max(U_star, lo, hi)[0]) == 2.0  # max(|u_min|, |u_max|)
    inf = jnp.array([jnp.inf])
    assert float(data.u_max(U_star, -inf, inf)[0]) == pytest.approx(0.5)  # no limit: max |u*|
    ds = data.sample(sys_, X_star, U_star, jax.random.key(0), 4000, 0.05, 0.0, lo, hi)
    dU = np.asarray(ds.U - U_star)
    assert dU.std() == pytest.approx(0.05 * 2.0, rel=0.02)
    wide = data.sample(sys_, X_star, U_star, jax.random.key(0), 4000, 1.0, 0.0, lo, hi)
    assert float(wide.U.min()) == -2.0 and float(wide.U.max()) == 1.0  # clipped to the limits
    np.testing.assert_allclose(wide.X, rollout(sys_, wide.X[:, 0], wide.U), atol=1e-12)


@pytest.mark.slow  # over 5 s: the fast tier's budget
def test_split_by_trajectory_and_transitions(systems):
    sys_ = systems("pendulum")
    X_star = jnp.zeros((6, 2)).at[:, 0].set(np.pi)
    U_star = jnp.ones((5, 1))
    ds = data.sample(sys_, X_star, U_star, jax.random.key(1), 50, 0.1, x0_sigma=0.01)
    train, test = data.split(ds, jax.random.key(2), 0.1)
    assert train.X.shape == (45, 6, 2) and test.X.shape == (5, 6, 2)
    rows = {tuple(np.asarray(r).ravel()) for r in jnp.concatenate([train.U, test.U])}
    assert len(rows) == 50  # a partition of the trajectories
    tr = data.transitions(train)
    assert tr.x.shape == (45 * 5, 2) and tr.u.shape == (225, 1)
    np.testing.assert_array_equal(tr.x_next[0], train.X[0, 1])
    bad = data.Dataset(train.X.at[0, 3].set(jnp.nan), train.U)
    assert data.transitions(bad).x.shape[0] == 225 - 2  # both transitions touching the NaN


@pytest.mark.slow
def test_seeds_differ_but_share_the_distribution(systems):
    sys_ = systems("pendulum")
    X_star = jnp.zeros((6, 2))
    U_star = 0.5 * jnp.ones((5, 1))
    sets = data.sample_seeds(sys_, X_star, U_star, jax.random.split(jax.random.key(3), 3), 400, 0.3)
    assert sets.X.shape == (3, 400, 6, 2)
    stds = [float(jnp.std(sets.U[i] - U_star)) for i in range(3)]
    assert not np.allclose(sets.U[0], sets.U[1])
    np.testing.assert_allclose(stds, 0.15, rtol=0.05)


def test_split_transitions_and_the_design_matrix_compile_one_program_each():
    """Each is one program (eager, every operation compiled on its own: 17 to 29 programs
    here for each new data shape); a non-finite entry still drops its transition."""
    from jax import monitoring

    from mjx_surrogate.surrogates import library, sindy

    compiles = []

    def listener(event, duration, **kw):
        if event == "/jax/core/compile/backend_compile_duration":
            compiles.append(event)

    rng = np.random.default_rng(7)
    X, U = jnp.asarray(rng.normal(size=(13, 9, 3))), jnp.asarray(rng.normal(size=(13, 8, 2)))
    spec, key, x, u = library.parse("poly2_trig", (0,), 1), jax.random.key(0), X[0, :-1], U[0]
    monitoring.register_event_duration_secs_listener(listener)
    try:
        counts = []
        for call in (
            lambda: data.split(data.Dataset(X, U), key),
            lambda: data.transitions(data.Dataset(X, U)),
            lambda: sindy.design(spec, x, u),
        ):
            compiles.clear()
            jax.block_until_ready(call())
            counts.append(len(compiles))
    finally:
        monitoring.unregister_event_duration_listener(listener)
    assert counts == [1, 1, 1], counts
    tr = data.transitions(data.Dataset(X.at[2, 3, 1].set(jnp.nan), U))
    assert tr.x.shape == (13 * 8 - 2, 3) and bool(jnp.isfinite(tr.x).all())
