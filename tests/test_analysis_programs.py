"""The analysis' host-side helpers compile as whole programs: one per helper and shape (run
eagerly, each of their operations compiled on its own, 5 to 60 programs for each new
shape), and new values of the same shapes compile nothing."""

import jax
import jax.numpy as jnp
import numpy as np
from jax import monitoring

from mjx_surrogate.analysis import evaluation, locality, spectra
from mjx_surrogate.identification import data, step_models, sysid
from mjx_surrogate.surrogates import mlp


def _compiles(call) -> int:
    """Backend compiles during call() (the persistent cache keeps none of these small ones)."""
    seen = []

    def listener(event, duration, **kw):
        if event == "/jax/core/compile/backend_compile_duration":
            seen.append(event)

    monitoring.register_event_duration_secs_listener(listener)
    try:
        jax.block_until_ready(call())
    finally:
        monitoring.unregister_event_duration_listener(listener)
    return len(seen)


def _step(x, u):
    return x + 0.1 * jnp.sin(x) + 0.05 * jnp.concatenate([u, u], -1)


def test_each_helper_is_one_program_and_new_values_compile_nothing():
    rng = np.random.default_rng(0)
    z, y = rng.normal(size=(2, 64, 3)), rng.normal(size=(2, 64, 2))
    spec = mlp.MLPSpec(widths=(4,), batch_size=32, epochs=1)
    keys = jax.random.split(jax.random.key(0), 2)
    both = mlp.train_seeds(spec, keys, z, y, z, y)
    assert _compiles(lambda: mlp.unstack(both, 0)) == 1
    assert _compiles(lambda: mlp.unstack(both, 1)) == 0
    model = mlp.unstack(both, 1).model
    T, n, nx, nu = 4, 12, 2, 1
    X, U = rng.normal(size=(T + 1, nx)), rng.normal(size=(T, nu))
    dX, dU = rng.normal(size=(n, T + 1, nx)), rng.normal(size=(n, T, nu))
    ltv = step_models.fit_ltv(data.Dataset(X + dX, U + dU), X, U).as_pytree()
    theta, coef = rng.normal(size=(10, 3)), rng.normal(size=(3, 2))
    helpers = {
        "mlp_gram": lambda v: spectra.mlp_gram(model, z[0, :8] + v),
        "mlp_descent_direction": lambda v: spectra.mlp_descent_direction(model, z[0, :8] + v, y[0, :8]),
        "error_projections": lambda v: spectra.error_projections([theta + v, theta], [y[0, :10]] * 2, coef),
        "fit_from_trajectories": lambda v: sysid.fit_from_trajectories(dX[:9] + v, dU[:9]),
        "finite_difference_jacobians": lambda v: sysid.finite_difference_jacobians(_step, X + v, U),
        "prediction_errors": lambda v: evaluation.prediction_errors(ltv, data.Dataset(X + dX + v, U + dU))[1],
        "u_max": lambda v: data.u_max(U + v),
        "relative_spread": lambda v: locality.relative_spread(X + dX + v, X),
    }
    first = {name: _compiles(lambda: f(0.0)) for name, f in helpers.items()}
    again = {name: _compiles(lambda: f(0.5)) for name, f in helpers.items()}
    # prediction_errors: the predictions' program and the one-step RMSE's
    assert first == {name: 2 if name == "prediction_errors" else 1 for name in helpers}, first
    assert again == dict.fromkeys(helpers, 0), again
