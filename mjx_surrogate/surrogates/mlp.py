"""MLP surrogates (Flax NNX + optax): [x, u] -> x_{t+1} (or the increment x_{t+1} - x_t).

The paper's network is [x, u] -> 32 -> ReLU -> 64 -> ReLU -> x_next, trained with Adam
(lr 1e-4, weight decay 1e-6 as an L2 term added to the gradient, as PyTorch's Adam does),
minibatches of 256 and the mean-squared error. Inputs and targets are standardised with
the training set's mean and standard deviation; the loss is the MSE of standardised
targets. Training is one jitted ``lax.while_loop`` over epochs (all of them, or until the
stopping tests of ``MLPSpec`` holds), each a ``lax.scan`` over minibatches of a fresh
permutation drawn from the key (:func:`shuffled`); parameters are kept at chosen
checkpoint epochs for the analysis. Early stopping (``patience``) watches the loss on a
validation set held out of the training data and returns the parameters of its best
epoch, as Keras's ``EarlyStopping(restore_best_weights=True)`` does. ``train_seeds``
trains K networks over K (key, data set) pairs in one program (vmapped on accelerators,
one after another on CPU devices; spread over a device mesh if given).
"""

from __future__ import annotations

from functools import partial
from typing import NamedTuple, Tuple

import jax
import jax.numpy as jnp
import numpy as np
import optax
from flax import nnx, struct
from jax.sharding import Mesh

from mjx_surrogate import sharding


class MLPSpec(NamedTuple):
    widths: Tuple[int, ...] = (32, 64)
    increment: bool = False
    learning_rate: float = 1e-4
    weight_decay: float = 1e-6
    batch_size: int = 256
    epochs: int = 200  # the most epochs; all of them unless the stopping test below ends earlier
    checkpoints: Tuple[int, ...] = ()  # epochs (0 = before training) whose params are kept
    stop_window: int = 0  # > 0: stop once the best test loss fell by less than
    stop_rel_tol: float = 0.0  # stop_rel_tol (relative) over the last stop_window epochs
    patience: int = 0  # > 0: stop once the validation loss has not improved for this many
    # epochs and return the best validation epoch's parameters (needs a validation set)


class Net(nnx.Module):
    """Fully connected ReLU network; the last layer is linear."""

    def __init__(self, sizes: Tuple[int, ...], rngs: nnx.Rngs):
        self.layers = nnx.List([nnx.Linear(a, b, rngs=rngs) for a, b in zip(sizes[:-1], sizes[1:])])

    def __call__(self, z: jax.Array) -> jax.Array:
        for layer in self.layers[:-1]:
            z = nnx.relu(layer(z))
        return self.layers[-1](z)


class Normalizer(NamedTuple):
    z_mean: jax.Array  # [nz]
    z_std: jax.Array
    y_mean: jax.Array  # [nx]
    y_std: jax.Array


@struct.dataclass
class MLPModel:
    params: nnx.State
    norm: Normalizer
    graphdef: nnx.GraphDef = struct.field(pytree_node=False)
    increment: bool = struct.field(pytree_node=False, default=False)

    def step(self, x: jax.Array, u: jax.Array) -> jax.Array:
        """x [nx], u [nu] -> x_next [nx] (any leading batch axes)."""
        z = jnp.concatenate([x, u], axis=-1)
        y = apply(self.graphdef, self.params, self.norm, z)
        return x + y if self.increment else y


class TrainResult(NamedTuple):
    model: MLPModel
    train_loss: jax.Array  # [epochs] mean minibatch loss per epoch (standardised MSE); NaN after a stop
    test_loss: jax.Array  # [epochs] full test-set loss after each epoch; NaN after a stop
    checkpoints: nnx.State  # params with a leading [n_checkpoints] axis
    epochs_run: jax.Array  # [] epochs trained (spec.epochs unless the stopping test ended earlier)
    val_loss: jax.Array | None = None  # [epochs] validation loss after each epoch (with a validation set)
    best_epoch: jax.Array | None = None  # [] the epoch (1-based) whose parameters are returned


def graphdef(spec: MLPSpec, nz: int, nx: int) -> nnx.GraphDef:
    return nnx.split(Net((nz, *spec.widths, nx), nnx.Rngs(0)))[0]


def init_params(spec: MLPSpec, key: jax.Array, nz: int, nx: int) -> nnx.State:
    return nnx.split(Net((nz, *spec.widths, nx), nnx.Rngs(key)))[1]


def apply(gdef: nnx.GraphDef, params: nnx.State, norm: Normalizer, z: jax.Array) -> jax.Array:
    """Network output in physical units: z [..., nz] -> y [..., nx]."""
    zs = ((z - norm.z_mean) / norm.z_std).astype(jnp.float32)
    ys = nnx.merge(gdef, params)(zs)
    return ys.astype(z.dtype) * norm.y_std + norm.y_mean


def normalizer(z: jax.Array, y: jax.Array) -> Normalizer:
    std = lambda a: jnp.where(a.std(0) > 0, a.std(0), 1.0)  # noqa: E731
    return Normalizer(z.mean(0), std(z), y.mean(0), std(y))


def targets(x: jax.Array, x_next: jax.Array, increment: bool) -> jax.Array:
    return x_next - x if increment else x_next


def optimizer(spec: MLPSpec) -> optax.GradientTransformation:
    return optax.chain(optax.add_decayed_weights(spec.weight_decay), optax.adam(spec.learning_rate))


@partial(jax.jit, static_argnames=("spec",))
def train(
    spec: MLPSpec,
    key: jax.Array,
    z: jax.Array,
    y: jax.Array,
    z_test: jax.Array,
    y_test: jax.Array,
    z_val: jax.Array | None = None,
    y_val: jax.Array | None = None,
) -> TrainResult:
    """Train one network on z [M, nz] -> y [M, nx]; test losses on z_test, y_test. With a
    validation set (z_val [V, nz], y_val [V, nx]) the stopping tests watch its loss
    instead of the test loss; ``spec.patience`` needs one."""
    M, nz = z.shape
    nx = y.shape[-1]
    if M < spec.batch_size:
        raise ValueError(f"mlp.batch_size: {spec.batch_size} exceeds the {M} training transitions")
    if spec.patience > 0 and z_val is None:
        raise ValueError("mlp.patience: early stopping needs a validation set (z_val, y_val)")
    gdef = graphdef(spec, nz, nx)
    k_init, k_epochs = jax.random.split(key)
    params = init_params(spec, k_init, nz, nx)
    norm = normalizer(z, y)
    zs = ((z - norm.z_mean) / norm.z_std).astype(jnp.float32)
    ys = ((y - norm.y_mean) / norm.y_std).astype(jnp.float32)
    zt = ((z_test - norm.z_mean) / norm.z_std).astype(jnp.float32)
    yt = ((y_test - norm.y_mean) / norm.y_std).astype(jnp.float32)
    if z_val is None:
        zv, yv = zt, yt
    else:
        zv = ((z_val - norm.z_mean) / norm.z_std).astype(jnp.float32)
        yv = ((y_val - norm.y_mean) / norm.y_std).astype(jnp.float32)
    opt = optimizer(spec)
    n_steps = M // spec.batch_size
    ckpt = jnp.asarray(spec.checkpoints or (0,), jnp.int32)

    def loss_fn(p, zb, yb):
        return jnp.mean((nnx.merge(gdef, p)(zb) - yb) ** 2)

    def sgd_step(carry, idx):
        p, s = carry
        loss, g = jax.value_and_grad(loss_fn)(p, zs[idx], ys[idx])
        upd, s = opt.update(g, s, p)
        return (optax.apply_updates(p, upd), s), loss

    keys = jax.random.split(k_epochs, spec.epochs)
    W = spec.stop_window

    def epoch(c):
        e, p, s, saved, tr, te, va, best, kept, at, _ = c
        perm = shuffled(keys[e], M)[: n_steps * spec.batch_size]
        (p, s), losses = jax.lax.scan(sgd_step, (p, s), perm.reshape(n_steps, spec.batch_size))
        saved = _keep(saved, p, ckpt, e + 1)
        test = loss_fn(p, zt, yt)
        held = test if z_val is None else loss_fn(p, zv, yv)
        better = held < best[e - 1]  # best[-1] is inf until the end
        best = best.at[e].set(jnp.minimum(held, best[e - 1]))
        kept = jax.tree.map(lambda a, b: jnp.where(better, a, b), p, kept)
        at = jnp.where(better, e + 1, at)
        # the convergence test: the best held-out loss fell by less than stop_rel_tol in W epochs
        stop = (W > 0) & (e >= W) & (best[e] > (1.0 - spec.stop_rel_tol) * best[jnp.maximum(e - W, 0)])
        # early stopping: no better validation loss in the last `patience` epochs
        stop |= (spec.patience > 0) & (e + 1 - at >= spec.patience)
        tr, te, va = tr.at[e].set(losses.mean()), te.at[e].set(test), va.at[e].set(held)
        return e + 1, p, s, saved, tr, te, va, best, kept, at, stop

    saved = jax.tree.map(lambda a: jnp.zeros((ckpt.shape[0],) + a.shape, a.dtype), params)
    saved = _keep(saved, params, ckpt, 0)
    nan = jnp.full((spec.epochs,), jnp.nan, jnp.float32)
    inf = jnp.full_like(nan, jnp.inf)
    init = (jnp.int32(0), params, opt.init(params), saved, nan, nan, nan, inf, params, jnp.int32(0), False)
    e, params, _, saved, tr, te, va, _, kept, at, _ = jax.lax.while_loop(
        lambda c: (c[0] < spec.epochs) & ~c[-1], epoch, init
    )
    if spec.patience > 0:
        params = kept
    else:
        at = e
    model = MLPModel(params, norm, gdef, spec.increment)
    return TrainResult(model, tr, te, saved, e, None if z_val is None else va, at)


def shuffled(key: jax.Array, n: int) -> jax.Array:
    """A uniformly random permutation of range(n), [n] int32, from a single one-operand sort:
    64-bit keys whose high bits are random and whose low ceil(log2 n) bits hold the index
    (a tie of the random bits, odds about n^2 / 2^(65 - log2 n), falls back on the index).
    ``jax.random.permutation`` sorts (key, index) pairs two or three times: on CPU 14.4 ms
    against 1.1 ms for n = 25,600, most of an SGD epoch of the paper's network
    (docs/performance.md). Without 64-bit types (or n > 2^32) it is what this returns."""
    b = max(int(n - 1).bit_length(), 1)
    if not jax.config.read("jax_enable_x64") or b > 32:
        return jax.random.permutation(key, n)
    low = jnp.uint64((1 << b) - 1)
    packed = (jax.random.bits(key, (n,), jnp.uint64) & ~low) | jnp.arange(n, dtype=jnp.uint64)
    return (jnp.sort(packed) & low).astype(jnp.int32)


def validation_split(
    key: jax.Array, n: int, fraction: float, block: int = 1
) -> tuple[np.ndarray, np.ndarray]:
    """Indices (train, validation) of n transitions: the validation set is whole blocks of
    ``block`` consecutive transitions (a data set's trajectories, so that no trajectory
    feeds both), ``fraction`` of the blocks (at least one) drawn by ``key``; a trailing
    partial block stays in training."""
    blocks = max(n // block, 1)
    n_val = min(max(1, round(fraction * blocks)), blocks - 1) if blocks > 1 else 0
    chosen = np.asarray(jax.random.permutation(key, blocks))[:n_val]
    held = np.isin(np.arange(n) // block, chosen)
    return np.flatnonzero(~held), np.flatnonzero(held)


def _keep(saved, params, ckpt: jax.Array, epoch: jax.Array):
    """Write params into the checkpoint slots whose epoch equals ``epoch``."""
    hit = ckpt == epoch  # [n_ckpt]

    def put(buf, a):
        h = hit.reshape((-1,) + (1,) * a.ndim)
        return jnp.where(h, a[None], buf)

    return jax.tree.map(put, saved, params)


@partial(jax.jit, static_argnames=("spec", "mesh"))
def train_seeds(
    spec: MLPSpec,
    keys: jax.Array,
    z: jax.Array,
    y: jax.Array,
    z_test: jax.Array,
    y_test: jax.Array,
    z_val: jax.Array | None = None,
    y_val: jax.Array | None = None,
    mesh: Mesh | None = None,
) -> TrainResult:
    """K networks at once: keys [K], z [K, M, nz], y [K, M, nx] (one data set per seed),
    test sets [K, M_test, ...] and optional validation sets [K, V, ...] as :func:`train`'s,
    the K trainings spread over ``mesh`` (:mod:`mjx_surrogate.sharding`), each with its own
    stopping epoch (:func:`_over_seeds`)."""
    if z_val is None:
        many = lambda *a: _over_seeds(lambda k, a, b, c, d: train(spec, k, a, b, c, d), *a)  # noqa: E731
        return sharding.map_batch(many, mesh, keys, z, y, z_test, y_test)
    many = lambda *a: _over_seeds(partial(train, spec), *a)  # noqa: E731
    return sharding.map_batch(many, mesh, keys, z, y, z_test, y_test, z_val, y_val)


def _over_seeds(fn, *args):
    """fn over the leading (seed) axis: vmapped on an accelerator, where the networks train
    side by side; on CPU devices one after another (``lax.map``), each seed stopping at its
    own epoch, where a vmapped ``while_loop`` computes every seed's masked epochs until the
    last one stops and batching networks this small gains nothing (5 seeds on the cartpole
    control study's data: 103.9 s against 174.9 s, ``benchmarks/mlp_seeds.py``)."""
    return sharding.over_leading_axis(fn, *args, lockstep=jax.default_backend() != "cpu")


@jax.jit
def unstack(result: TrainResult, i: int | jax.Array) -> TrainResult:
    """The i-th network of a ``train_seeds`` result."""
    m = result.model
    take = lambda t: jax.tree.map(lambda a: a[i], t)  # noqa: E731
    model = MLPModel(take(m.params), take(m.norm), m.graphdef, m.increment)
    return TrainResult(model, *(take(a) for a in result[1:]))
