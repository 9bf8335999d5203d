"""The surrogate extension point: a protocol, a registry, one ``fit_all``.

A surrogate kind fits global models of the dynamics from transitions and a key; every
fitted model is a pytree with a jittable ``step(x [nx], u [nu]) -> x_next [nx]`` (the
:class:`Surrogate` protocol), so prediction, analysis and control use it unchanged. A new
kind is one module plus one :func:`register_surrogate` call (docs/extending.md). Kinds
built in: ``sindy`` (one model per library), ``mlp`` and ``pod_sindy`` (SINDy on POD modes).
"""

from __future__ import annotations

import time
from typing import Any, Callable, NamedTuple, Protocol

import jax
import jax.numpy as jnp
import numpy as np

from mjx_surrogate import sharding
from mjx_surrogate.errors import ConfigError, registered


class Surrogate(Protocol):
    def step(self, x: jax.Array, u: jax.Array) -> jax.Array: ...


class Fitted(NamedTuple):
    """A fitted surrogate: the model, fit metrics (JSON) and arrays worth keeping."""

    model: Surrogate
    info: dict
    arrays: dict = {}


class FitContext(NamedTuple):
    """What a kind may read while fitting: the resolved config, the system and the length
    of the data's trajectories (their transitions lie in consecutive blocks of it; None
    where unknown)."""

    config: Any  # mjx_surrogate.runs.config.Config
    system: Any  # mjx_surrogate.systems.System
    trajectory_length: int | None = None


class SurrogateKind(NamedTuple):
    """fit(ctx, train, test, key) -> {label: Fitted}; validate(config, system, n_train)
    raises ConfigError before any compile (``n_train``: training transitions); settings:
    the kind's own settings' defaults (a frozen dataclass instance, set as
    ``--surrogate.<name>.<field>``; ``fit`` reads the run's values with
    ``mjx_surrogate.settings_of(ctx.config, "surrogate", name)``). fit_seeds (optional):
    fit(ctx, trains, tests, keys) -> [{label: Fitted}] on K data sets of equal sizes at
    once (the seeds along a leading axis, spread over the system's mesh), each as ``fit``
    would fit it alone; without it :func:`fit_all_seeds` calls ``fit`` per data set."""

    fit: Callable[..., dict[str, Fitted]]
    validate: Callable[[Any, Any, int], None] = lambda config, system, n_train: None
    description: str = ""
    settings: Any = None
    fit_seeds: Callable[..., list[dict[str, Fitted]]] | None = None


SURROGATES: dict[str, SurrogateKind] = {}


def register_surrogate(name: str, kind: SurrogateKind) -> None:
    """Add ``kind`` under ``name`` (then valid in ``surrogate.kinds``)."""
    SURROGATES[name] = kind


def get_surrogate(name: str, field: str = "surrogate.kinds") -> SurrogateKind:
    return registered(SURROGATES, name, field, "surrogate kind")


def fit_all(ctx: FitContext, train, test, key: jax.Array, meter=None) -> dict[str, Fitted]:
    """Fit every kind of ``ctx.config.surrogate.kinds`` on Transitions ``train`` (``test``
    for held-out losses); kind i draws from ``fold_in(key, i)``. Labels stay in order.
    ``meter``: a :class:`mjx_surrogate.progress.StepMeter`, advanced once per kind."""
    return fit_all_seeds(ctx, [train], [test], [key], meter)[0]


def fit_all_seeds(
    ctx: FitContext, trains: list, tests: list, keys: list, meter=None
) -> list[dict[str, Fitted]]:
    """:func:`fit_all` on K data sets (``trains[s]``, ``tests[s]``, ``keys[s]``): the same
    models per data set, a kind with ``fit_seeds`` fitting all K at once. Per data set, in
    order; ``fit_s`` is each model's share of its kind's time."""
    out: list[dict[str, Fitted]] = [{} for _ in trains]
    for i, name in enumerate(ctx.config.surrogate.kinds):
        if meter is not None:
            meter.advance(f"fit {name}" + (f", {len(trains)} data sets" if len(trains) > 1 else ""))
        kind, kind_keys = get_surrogate(name), [jax.random.fold_in(k, i) for k in keys]
        t0 = time.perf_counter()
        if kind.fit_seeds is not None and len(trains) > 1:
            fitted = kind.fit_seeds(ctx, trains, tests, kind_keys)
        else:
            fitted = [kind.fit(ctx, tr, te, k) for tr, te, k in zip(trains, tests, kind_keys)]
        jax.block_until_ready([f.model for fs in fitted for f in fs.values()])
        share = (time.perf_counter() - t0) / max(sum(len(fs) for fs in fitted), 1)
        for s, fs in enumerate(fitted):
            for label, f in fs.items():
                out[s][label] = f._replace(info={"fit_s": share, **f.info})
    return out


# -- built-in kinds -------------------------------------------------------------------


def hinge_angles(system) -> tuple[int, ...]:
    """State indices of hinge-joint angles, a function black box's ``angle_pairs`` (the
    default trig coordinates)."""
    return tuple(q for q, _ in system.angle_pairs)


def library_specs(
    config, system, names: tuple[str, ...] | str | None = None, field: str = "surrogate.sindy.libraries"
) -> dict:
    """Resolved SINDy libraries by name (default: surrogate.sindy.libraries; a single name
    for a scalar field); a bad one raises ConfigError naming ``field[i]`` (``field`` for a
    single name), or surrogate.sindy.trig_coords / harmonics."""
    from mjx_surrogate.surrogates import library

    sc = config.surrogate.sindy
    coords = sc.trig_coords if sc.trig_coords is not None else hinge_angles(system)
    nz = system.nx + system.nu
    scalar = isinstance(names, str)
    out = {}
    for i, name in enumerate((names,) if scalar else sc.libraries if names is None else names):
        try:
            spec = library.parse(name, coords, sc.harmonics)
            library.validate(spec, nz)
        except library.SpecError as exc:
            where = (
                f"surrogate.sindy.{exc.part}"
                if exc.part in ("trig_coords", "harmonics")
                else field
                if scalar
                else f"{field}[{i}]"
            )
            raise ConfigError(where, exc.message) from None
        out[name] = spec
    return out


def _sindy_options(config) -> dict:
    """The least-squares options of surrogate.sindy (and increment), shared by the SINDy kinds."""
    s = config.surrogate.sindy
    return dict(
        increment=config.surrogate.increment,
        threshold=s.stlsq_threshold,
        alpha=s.stlsq_alpha,
        method=s.method,
    )


def _fit_sindy(ctx: FitContext, train, test, key) -> dict[str, Fitted]:
    from mjx_surrogate.surrogates import sindy

    x, u, x_next = sharding.on_one_device(train.x, train.u, train.x_next)  # rows spread: 3.3x slower
    out = {}
    for name, spec in library_specs(ctx.config, ctx.system).items():
        model = sindy.fit(spec, x, u, x_next, **_sindy_options(ctx.config))
        out[f"SINDy {name}"] = Fitted(
            model, {"n_features": int(model.coef.shape[0]), "nonzero": int(jnp.sum(model.coef != 0))}
        )
    return out


def mlp_spec(config):
    """surrogate.mlp -> the MLP's static spec."""
    from mjx_surrogate.surrogates.mlp import MLPSpec

    m = config.surrogate.mlp
    return MLPSpec(
        widths=tuple(m.widths),
        increment=config.surrogate.increment,
        learning_rate=m.learning_rate,
        weight_decay=m.weight_decay,
        batch_size=m.batch_size,
        epochs=m.epochs,
        checkpoints=tuple(m.checkpoints),
        stop_window=m.stop_window,
        stop_rel_tol=m.stop_rel_tol,
        patience=m.patience,
    )


def _fit_mlp(ctx: FitContext, train, test, key) -> dict[str, Fitted]:
    """ "MLP": trained as surrogate.mlp says (with ``patience``, to the minimum of a
    validation set of whole trajectories held out of ``train``); with
    ``fixed_epochs_beside`` N also "MLP N epochs", the paper's setting: all of ``train``
    for exactly N epochs from the same initialisation."""
    from mjx_surrogate.surrogates import mlp

    m = ctx.config.surrogate.mlp
    spec = mlp_spec(ctx.config)
    z, y = _pairs(train.x, train.u, train.x_next, spec.increment)  # NumPy: the splits index it on the host
    tests = _pairs(test.x, test.u, test.x_next, spec.increment)
    if spec.patience > 0:
        block = ctx.trajectory_length or 1
        k_val = jax.random.fold_in(key, 1)
        fit_i, val_i = mlp.validation_split(k_val, z.shape[0], m.validation_fraction, block)
        r = mlp.train(spec, key, z[fit_i], y[fit_i], *tests, z[val_i], y[val_i])
    else:
        r = mlp.train(spec, key, z, y, *tests)
    out = {"MLP": _mlp_fitted(r)}
    if m.fixed_epochs_beside > 0:
        fixed = spec._replace(epochs=m.fixed_epochs_beside, patience=0, stop_window=0, checkpoints=())
        out[f"MLP {m.fixed_epochs_beside} epochs"] = _mlp_fitted(mlp.train(fixed, key, z, y, *tests))
    return out


def _fit_mlp_seeds(ctx: FitContext, trains: list, tests: list, keys: list) -> list[dict[str, Fitted]]:
    """:func:`_fit_mlp` on K data sets at once (``mlp.train_seeds`` over the system's mesh):
    per data set its own validation split, initialisation and stopping epoch."""
    from mjx_surrogate.surrogates import mlp

    m = ctx.config.surrogate.mlp
    spec = mlp_spec(ctx.config)
    pairs = [_pairs(t.x, t.u, t.x_next, spec.increment) for t in trains]
    held = [_pairs(t.x, t.u, t.x_next, spec.increment) for t in tests]
    if len({(p[0].shape, h[0].shape) for p, h in zip(pairs, held)}) > 1:  # unequal sizes: one by one
        return [_fit_mlp(ctx, tr, te, k) for tr, te, k in zip(trains, tests, keys)]
    stack = lambda arrays: jnp.asarray(np.stack(arrays))  # noqa: E731
    z, y = stack([p[0] for p in pairs]), stack([p[1] for p in pairs])
    zt, yt = stack([h[0] for h in held]), stack([h[1] for h in held])
    K, mesh = len(trains), getattr(ctx.system, "mesh", None)
    if spec.patience > 0:
        block = ctx.trajectory_length or 1
        splits = [
            mlp.validation_split(jax.random.fold_in(k, 1), z.shape[1], m.validation_fraction, block)
            for k in keys
        ]
        fit_i, val_i = np.stack([f for f, _ in splits]), np.stack([v for _, v in splits])
        take = lambda a, idx: jnp.stack([a[s][idx[s]] for s in range(K)])  # noqa: E731
        args = (take(z, fit_i), take(y, fit_i), zt, yt, take(z, val_i), take(y, val_i))
    else:
        args = (z, y, zt, yt)
    trained = mlp.train_seeds(spec, jnp.stack(keys), *args, mesh=mesh)
    out = [{"MLP": _mlp_fitted(mlp.unstack(trained, s))} for s in range(K)]
    if m.fixed_epochs_beside > 0:
        fixed = spec._replace(epochs=m.fixed_epochs_beside, patience=0, stop_window=0, checkpoints=())
        both = mlp.train_seeds(fixed, jnp.stack(keys), z, y, zt, yt, mesh=mesh)
        for s in range(K):
            out[s][f"MLP {m.fixed_epochs_beside} epochs"] = _mlp_fitted(mlp.unstack(both, s))
    return out


def _pairs(x: jax.Array, u: jax.Array, x_next: jax.Array, increment: bool) -> tuple[np.ndarray, np.ndarray]:
    """The MLP's inputs z = [x, u] [n, nx + nu] and targets [n, nx] of transitions, as NumPy."""
    from mjx_surrogate.surrogates import mlp

    x = np.asarray(x)
    return np.concatenate([x, np.asarray(u)], -1), mlp.targets(x, np.asarray(x_next), increment)


def _mlp_fitted(r) -> Fitted:
    last = int(r.epochs_run) - 1
    info = {
        "epochs": int(r.epochs_run),
        "best_epoch": int(r.best_epoch),
        "final_train_loss": float(r.train_loss[last]),
        "final_test_loss": float(r.test_loss[last]),
    }
    arrays = {"train_loss": r.train_loss, "test_loss": r.test_loss}
    if r.val_loss is not None:
        info["best_validation_loss"] = float(r.val_loss[int(r.best_epoch) - 1])
        arrays["validation_loss"] = r.val_loss
    return Fitted(r.model, info, arrays)


def _validate_sindy(config, system, n_train: int) -> None:
    library_specs(config, system)


def _validate_mlp(config, system, n_train: int) -> None:
    m = config.surrogate.mlp
    b = m.batch_size
    kept = n_train if m.patience == 0 else int(n_train * (1 - m.validation_fraction))
    if b > kept:
        held = "" if m.patience == 0 else f" left after the validation set ({m.validation_fraction:g})"
        raise ConfigError(
            "surrogate.mlp.batch_size",
            f"{b} exceeds the {kept} training transitions{held} (data.n_traj x task.T)",
        )


def _pod_specs(config, system) -> dict:
    """surrogate.pod_sindy's libraries, parsed for rank + nu coordinates (ConfigError naming
    the field on a bad name or rank)."""
    from mjx_surrogate.surrogates import library

    pc = config.surrogate.pod_sindy
    if not 1 <= pc.rank <= system.nx:
        raise ConfigError(
            "surrogate.pod_sindy.rank", f"must be between 1 and nx = {system.nx}, got {pc.rank}"
        )
    out = {}
    for i, name in enumerate(pc.libraries):
        try:
            spec = library.parse(name, (), 1)
            library.validate(spec, pc.rank + system.nu)
        except library.SpecError as exc:
            raise ConfigError(f"surrogate.pod_sindy.libraries[{i}]", exc.message) from None
        out[name] = spec
    return out


def _fit_pod_sindy(ctx: FitContext, train, test, key) -> dict[str, Fitted]:
    from mjx_surrogate.surrogates import pod_sindy

    pc = ctx.config.surrogate.pod_sindy
    x, u, x_next = sharding.on_one_device(train.x, train.u, train.x_next)
    out = {}
    for name, spec in _pod_specs(ctx.config, ctx.system).items():
        options = _sindy_options(ctx.config)
        model, captured = pod_sindy.fit(spec, x, u, x_next, pc.rank, **options)
        info = {"n_features": int(model.reduced.coef.shape[0]), "rank": pc.rank, "pod_energy": captured}
        out[f"POD{pc.rank}-SINDy {name}"] = Fitted(model, info)
    return out


register_surrogate(
    "sindy", SurrogateKind(_fit_sindy, _validate_sindy, "SINDy-style least squares, one model per library")
)
register_surrogate(
    "mlp", SurrogateKind(_fit_mlp, _validate_mlp, "Flax MLP, the paper's", fit_seeds=_fit_mlp_seeds)
)
register_surrogate(
    "pod_sindy",
    SurrogateKind(
        _fit_pod_sindy,
        lambda config, system, n_train: _pod_specs(config, system) and None,
        "SINDy on the leading POD modes of the states (PDEs)",
    ),
)
