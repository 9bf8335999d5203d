"""Flax MLP surrogate: fits a smooth map, seeds by vmap, checkpoints, normalisation."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mjx_surrogate.surrogates import mlp

SPEC = mlp.MLPSpec(widths=(32, 64), learning_rate=3e-3, batch_size=64, epochs=60, checkpoints=(0, 30, 60))


def _data(key, n=2000):
    kz, _ = jax.random.split(key)
    z = jax.random.uniform(kz, (n, 3), minval=-1.0, maxval=1.0)
    x, u = z[:, :2], z[:, 2:]
    y = jnp.stack([x[:, 0] + 0.1 * jnp.sin(3 * x[:, 1]), x[:, 1] - 0.2 * x[:, 0] ** 2 + 0.1 * u[:, 0]], -1)
    return z, 10.0 + 5.0 * y  # an offset and scale the normaliser must absorb


@pytest.mark.slow
def test_fits_a_smooth_map_to_a_stated_loss():
    z, y = _data(jax.random.key(0))
    zt, yt = _data(jax.random.key(1), 500)
    res = mlp.train(SPEC, jax.random.key(2), z, y, zt, yt)
    assert res.train_loss.shape == (60,) and res.test_loss.shape == (60,)
    # standardised test MSE below 1e-3 means an RMSE of ~3 % of the target's std
    assert float(res.test_loss[-1]) < 1e-3
    pred = res.model.step(zt[:, :2], zt[:, 2:])
    rel = jnp.sqrt(jnp.mean((pred - yt) ** 2)) / jnp.std(yt)
    assert float(rel) < 0.05
    # checkpoint 0 holds the initial parameters, the last the final ones
    last = jax.tree.map(lambda a: a[-1], res.checkpoints)
    for a, b in zip(jax.tree.leaves(last), jax.tree.leaves(res.model.params)):
        np.testing.assert_array_equal(a, b)
    first = jax.tree.map(lambda a: a[0], res.checkpoints)
    init = mlp.init_params(SPEC, jax.random.split(jax.random.key(2))[0], 3, 2)
    # initialised inside the training program and alone: equal up to float32 round-off
    # (bit for bit at XLA's default code generation, not at the suite's -O0); one epoch
    # of Adam at 3e-3 moves them by up to 0.09
    for a, b in zip(jax.tree.leaves(first), jax.tree.leaves(init)):
        np.testing.assert_allclose(a, b, rtol=1e-6, atol=1e-7)


@pytest.mark.slow
def test_seeds_by_vmap_equal_separate_trainings():
    spec = SPEC._replace(epochs=3, checkpoints=())
    keys = jax.random.split(jax.random.key(5), 2)
    data = [_data(k, 512) for k in jax.random.split(jax.random.key(6), 2)]
    z = jnp.stack([d[0] for d in data])
    y = jnp.stack([d[1] for d in data])
    both = mlp.train_seeds(spec, keys, z, y, z[:, :100], y[:, :100])
    for i in range(2):
        one = mlp.train(spec, keys[i], z[i], y[i], z[i, :100], y[i, :100])
        np.testing.assert_allclose(mlp.unstack(both, i).train_loss, one.train_loss, rtol=1e-4)
    assert not np.allclose(both.train_loss[0], both.train_loss[1])


def test_increment_target_and_no_recompile():
    spec = SPEC._replace(epochs=2, increment=True, checkpoints=())
    z, y = _data(jax.random.key(7), 256)
    x = z[:, :2]
    res = mlp.train(spec, jax.random.key(0), z, mlp.targets(x, y, True), z, mlp.targets(x, y, True))
    out = res.model.step(x, z[:, 2:])
    np.testing.assert_allclose(
        out - x, mlp.apply(res.model.graphdef, res.model.params, res.model.norm, z), rtol=1e-6, atol=1e-6
    )
    n = mlp.train._cache_size()
    mlp.train(spec, jax.random.key(1), z, y, z, y)
    assert mlp.train._cache_size() == n


@pytest.mark.slow
def test_stopping_test_ends_training_where_the_rule_first_holds():
    """The run stops at the first epoch e >= W where the best test loss fell by less than
    tol over W epochs (checked on the stored losses in NumPy); vmapped seeds stop alone."""
    spec = SPEC._replace(epochs=400, checkpoints=(), stop_window=10, stop_rel_tol=0.05)
    z, y = _data(jax.random.key(8), 512)
    keys = jax.random.split(jax.random.key(9), 2)
    both = mlp.train_seeds(
        spec, keys, jnp.stack([z, z]), jnp.stack([y, y]), jnp.stack([z, z]), jnp.stack([y, y])
    )
    for i in range(2):
        r = mlp.unstack(both, i)
        n = int(r.epochs_run)
        te = np.asarray(r.test_loss)
        assert 10 < n < 400 and np.isfinite(te[:n]).all() and np.isnan(te[n:]).all()
        best = np.minimum.accumulate(te[:n])
        holds = [e >= 10 and best[e] > 0.95 * best[e - 10] for e in range(n)]
        assert holds.index(True) == n - 1
        one = mlp.train(spec, keys[i], z, y, z, y)  # alone: the same stop
        assert int(one.epochs_run) == n
    full = mlp.train(SPEC._replace(epochs=30, checkpoints=()), keys[0], z, y, z, y)
    assert int(full.epochs_run) == 30 and np.isfinite(np.asarray(full.test_loss)).all()


def test_early_stopping_returns_the_best_validation_epochs_network():
    """With patience P the run stops P epochs after its best validation loss (recomputed
    here from the returned network) and returns that epoch's network, not the last one;
    noisy targets and a small training set make the network overfit."""
    z, y = _data(jax.random.key(10), 1200)
    y = y + 2.0 * jax.random.normal(jax.random.key(11), y.shape)
    fit_i, val_i = mlp.validation_split(jax.random.key(12), 1200, 0.5, block=20)
    spec = mlp.MLPSpec(widths=(64, 64), learning_rate=1e-2, batch_size=32, epochs=300, patience=8)
    r = mlp.train(spec, jax.random.key(13), z[fit_i], y[fit_i], z[:64], y[:64], z[val_i], y[val_i])
    n, best = int(r.epochs_run), int(r.best_epoch)
    va = np.asarray(r.val_loss)
    assert n < 300 and best == int(np.nanargmin(va)) + 1 and n == best + 8
    assert np.isfinite(va[:n]).all() and np.isnan(va[n:]).all()
    norm = r.model.norm
    ys = (y[val_i] - norm.y_mean) / norm.y_std
    ys_hat = (r.model.step(z[val_i, :2], z[val_i, 2:]) - norm.y_mean) / norm.y_std
    returned = float(jnp.mean((ys_hat - ys) ** 2))
    np.testing.assert_allclose(returned, va[best - 1], rtol=1e-4)
    assert va[n - 1] > va[best - 1]  # the last epoch's network was worse: it is not the one returned
    with pytest.raises(ValueError, match="mlp.patience"):
        mlp.train(spec, jax.random.key(13), z, y, z, y)


def test_the_validation_set_is_whole_blocks_drawn_by_the_key():
    tr, va = mlp.validation_split(jax.random.key(0), 1005, 0.1, block=50)
    assert len(va) == 2 * 50 and len(tr) == 1005 - 100 and not set(tr) & set(va)
    assert set(np.unique(va // 50).tolist()) <= set(range(20)) and len(np.unique(va // 50)) == 2
    assert all(b * 50 + i in set(va) for b in np.unique(va // 50) for i in range(50))
    assert set(range(1000, 1005)) <= set(tr)  # the trailing partial block trains
    other = mlp.validation_split(jax.random.key(1), 1005, 0.1, block=50)[1]
    assert not np.array_equal(va, other)


def test_one_sort_shuffles_are_uniform_permutations():
    """``shuffled`` (the epochs' minibatch order): a permutation of range(n) for every key,
    all 120 orders of 5 items equally likely over 24,000 keys (chi-square, 119 degrees of
    freedom, below its 1e-4 quantile 190), a size whose index needs every low bit (n = 8)
    and one past a power of two (n = 9); without 64-bit types it is jax.random.permutation."""
    keys = jax.random.split(jax.random.key(0), 24_000)
    perms = np.asarray(jax.jit(jax.vmap(lambda k: mlp.shuffled(k, 5)))(keys))
    np.testing.assert_array_equal(np.sort(perms, axis=1), np.broadcast_to(np.arange(5), perms.shape))
    _, counts = np.unique(perms, axis=0, return_counts=True)
    assert len(counts) == 120
    chi2 = float(((counts - 200.0) ** 2 / 200.0).sum())
    assert chi2 < 190.0, chi2
    for n in (1, 8, 9, 1000):
        p = np.asarray(mlp.shuffled(jax.random.key(n), n))
        assert p.dtype == np.int32 and sorted(p.tolist()) == list(range(n))
    assert not np.array_equal(mlp.shuffled(jax.random.key(1), 1000), mlp.shuffled(jax.random.key(2), 1000))
    with jax.enable_x64(False):
        np.testing.assert_array_equal(
            mlp.shuffled(jax.random.key(3), 50), jax.random.permutation(jax.random.key(3), 50)
        )
