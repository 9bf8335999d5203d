"""fit_all_seeds: K data sets fitted at once (the MLPs along a leading axis) give each data
set the models fit_all gives it alone."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mjx_surrogate.identification.data import Transitions
from mjx_surrogate.surrogates import FitContext, fit_all, fit_all_seeds, registry
from mjx_surrogate.systems import make_system


def _config(patience: int):
    from configs.smoke_control import CONFIG

    mlp = dataclasses.replace(
        CONFIG.surrogate.mlp,
        epochs=40,
        batch_size=32,
        patience=patience,
        learning_rate=3e-3,
        fixed_epochs_beside=4,
    )
    surrogate = dataclasses.replace(CONFIG.surrogate, kinds=("sindy", "mlp"), mlp=mlp)
    return dataclasses.replace(CONFIG, surrogate=surrogate)


def _data_set(system, key, n_traj: int, T: int) -> Transitions:
    """Transitions of the pendulum's own step from random states and controls, laid out as
    n_traj blocks of T (a validation split holds out whole blocks)."""
    kx, ku = jax.random.split(key)
    x = jax.random.normal(kx, (n_traj * T, system.nx))
    u = jax.random.normal(ku, (n_traj * T, system.nu))
    return Transitions(x, u, jax.jit(jax.vmap(system.step))(x, u))


@pytest.mark.slow  # over 5 s: the fast tier's budget
@pytest.mark.parametrize("patience", [3, 0])
def test_seeds_at_once_give_each_data_set_its_own_fit(patience):
    system = make_system("pendulum", backend="native")
    ctx = FitContext(_config(patience), system, 10)
    keys = [jax.random.key(s) for s in range(3)]
    trains = [_data_set(system, jax.random.fold_in(k, 1), 12, 10) for k in keys]
    tests = [_data_set(system, jax.random.fold_in(k, 2), 3, 10) for k in keys]
    together = fit_all_seeds(ctx, trains, tests, keys)
    assert len(together) == 3
    x, u = tests[0].x[:50], tests[0].u[:50]
    predictions = []
    for s in range(3):
        alone = fit_all(ctx, trains[s], tests[s], keys[s])
        assert list(together[s]) == list(alone) == ["SINDy cubic_trig", "MLP", "MLP 4 epochs"]
        sindy_a, sindy_t = alone["SINDy cubic_trig"].model, together[s]["SINDy cubic_trig"].model
        np.testing.assert_array_equal(sindy_t.coef, sindy_a.coef)
        for label in ("MLP", "MLP 4 epochs"):
            a, t = alone[label], together[s][label]
            assert {k: t.info[k] for k in ("epochs", "best_epoch")} == {
                k: a.info[k] for k in ("epochs", "best_epoch")
            }
            step = lambda m: jax.vmap(m.step)(x, u)  # noqa: E731
            np.testing.assert_allclose(step(t.model), step(a.model), rtol=1e-4, atol=1e-5)
            np.testing.assert_allclose(t.arrays["test_loss"], a.arrays["test_loss"], rtol=1e-4)
        predictions.append(np.asarray(jax.vmap(together[s]["MLP"].model.step)(x, u)))
        assert together[s]["MLP"].info["fit_s"] > 0
    assert not np.allclose(predictions[0], predictions[1])  # each seed its own network
    if patience:  # early stopping: each seed at its own epoch (here 13, 8, 13), as alone
        assert len({f["MLP"].info["epochs"] for f in together}) > 1
        assert all(f["MLP"].info["epochs"] == f["MLP"].info["best_epoch"] + patience for f in together)


def test_a_kind_without_fit_seeds_is_fitted_per_data_set(monkeypatch):
    """An extension kind that declares only ``fit`` is called once per data set, with the
    key ``fit_all`` would give it."""
    seen = []

    def fit(ctx, train, test, key):
        seen.append((int(train.x.shape[0]), jax.random.key_data(key).tolist()))
        return {"mean": registry.Fitted(jnp.mean(train.x_next, 0), {})}

    monkeypatch.setitem(registry.SURROGATES, "mean_only", registry.SurrogateKind(fit))
    cfg = _config(0)
    cfg = dataclasses.replace(cfg, surrogate=dataclasses.replace(cfg.surrogate, kinds=("mean_only",)))
    system = make_system("pendulum", backend="native")
    keys = [jax.random.key(7), jax.random.key(8)]
    trains = [_data_set(system, k, 2 + s, 10) for s, k in enumerate(keys)]
    out = fit_all_seeds(FitContext(cfg, system, 10), trains, trains, keys)
    assert [list(o) for o in out] == [["mean"], ["mean"]]
    expected = [
        (20 + 10 * s, jax.random.key_data(jax.random.fold_in(k, 0)).tolist()) for s, k in enumerate(keys)
    ]
    assert seen == expected
