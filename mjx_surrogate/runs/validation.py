"""Static checks of a config, each refused with :class:`~mjx_surrogate.errors.ConfigError`
naming the field, before any model is built (``validate_static``): types and choices, every
section's own ``check`` (beside its fields, :mod:`mjx_surrogate.runs.config`), then what
needs a registry: the names of registered extensions, what the chosen scheme supports, the
function black boxes' settings. The checks that need the model are
:mod:`mjx_surrogate.runs.resolution`'s."""

from __future__ import annotations

import dataclasses
import typing

from mjx_surrogate.control.model_strategies import get_model_strategy
from mjx_surrogate.errors import ConfigError
from mjx_surrogate.identification.sysid import SCHEMES, SysIdParams, get_scheme
from mjx_surrogate.runs.config import Config, SystemConfig, from_dict
from mjx_surrogate.runs.experiment_kinds import get_experiment
from mjx_surrogate.runs.extension_settings import check_extensions, settings_of
from mjx_surrogate.surrogates.registry import get_surrogate
from mjx_surrogate.systems.registry import USER_FUNCTION, is_function_system

_SYSID = SysIdParams()


def _check_types(cfg: Config) -> None:
    """Every field holds a value of its declared type (choices included), also when the
    config was built in Python (a notebook, a .py config) rather than parsed from a file."""
    if not isinstance(cfg, Config):
        raise ConfigError("CONFIG", f"expected a mjx_surrogate.runs.config.Config, got {type(cfg).__name__}")
    hints = typing.get_type_hints(Config)
    if not isinstance(cfg.extensions, dict):
        raise ConfigError("extensions", f"expected a mapping, got {type(cfg.extensions).__name__}")
    for f in dataclasses.fields(cfg):
        if f.name == "extensions":  # checked by extension_settings.check_extensions
            continue
        section = getattr(cfg, f.name)
        if not isinstance(section, hints[f.name]):
            raise ConfigError(f.name, f"expected a {f.name} section, got {type(section).__name__}")
    from_dict(Config, dataclasses.asdict(cfg))


def validate_static(cfg: Config) -> None:
    """Checks that need no model: types and choices, then every section's own ``check``
    (signs, ranges, finiteness: :meth:`Config.check`), then what needs a registry (the
    function black boxes' settings, the names of registered extensions and what each
    supports, the extensions' own settings)."""
    _check_types(cfg)
    cfg.check()
    _check_function_system(cfg.system)
    _check_registered(cfg)


def _check_registered(cfg: Config) -> None:
    """Names that select a registered extension (identification scheme, surrogate kinds,
    experiment kind) and the extensions' own settings."""
    get_experiment(cfg.experiment.kind)

    s = cfg.sysid
    scheme = get_scheme(s.scheme, "sysid.scheme")
    get_model_strategy(cfg.solver.model_strategy, "solver.model_strategy")
    mpc_name = cfg.mpc.sysid.scheme or s.scheme
    mpc_scheme = get_scheme(mpc_name, "mpc.sysid.scheme")
    for field, every, used, name in (
        ("sysid.every", s.every, scheme, s.scheme),
        ("mpc.sysid.every", cfg.mpc.sysid.every, mpc_scheme, mpc_name),
    ):
        if every > 1 and not used.one_step:
            one_step = ", ".join(n for n, s in SCHEMES.items() if s.one_step)
            raise ConfigError(
                field,
                f"> 1 needs a one-step scheme ({one_step}); {name!r} identifies from rollouts",
            )
    if settings_of(cfg, "mpc", "d2c").reuse_tol > 0 and mpc_scheme.reduced:
        raise ConfigError(
            "mpc.d2c.reuse_tol",
            f"carries full-order models only; {mpc_name!r} identifies reduced ones: give 0 or another scheme",
        )
    if (s.significance or 0.0) > 0 and not scheme.t_test:
        tested = ", ".join(n for n, sc in SCHEMES.items() if sc.t_test)
        raise ConfigError(
            "sysid.significance", f"needs a scheme with a t-test ({tested}); {s.scheme!r} has none: give 0"
        )
    if s.rank_tol != _SYSID.rank_tol and not scheme.reduced:
        reduced = ", ".join(n for n, sc in SCHEMES.items() if sc.reduced)
        raise ConfigError(
            "sysid.rank_tol", f"only a reduced scheme ({reduced}) has a basis; {s.scheme!r} has none"
        )
    if s.design != "gaussian" and not scheme.one_step:
        raise ConfigError(
            "sysid.design", f"{s.design!r} needs a one-step scheme; {s.scheme!r} draws its own perturbations"
        )
    if not cfg.surrogate.kinds:
        raise ConfigError("surrogate.kinds", "give one or more surrogate kinds")
    for i, name in enumerate(cfg.surrogate.kinds):
        get_surrogate(name, f"surrogate.kinds[{i}]")
    check_extensions(cfg)


def _check_function_system(sy: SystemConfig) -> None:
    """A function black box (system.entry, lorenz, f8) has no MuJoCo settings."""
    if (sy.name == USER_FUNCTION) != (sy.entry is not None):
        field, need = ("system.entry", "required") if sy.entry is None else ("system.entry", "only valid")
        raise ConfigError(
            field, f"{need} with system.name='{USER_FUNCTION}' (a MODULE:ATTRIBUTE or FILE.py:ATTRIBUTE)"
        )
    if sy.model_copy is not None and sy.name != "mjcf":
        raise ConfigError("system.model_copy", "only valid with system.name='mjcf'")
    if not is_function_system(sy.name):
        return
    for field in ("mjcf_path", "model_copy", "substeps", "control_dt", "timestep", "native_threads"):
        if getattr(sy, field) is not None:
            raise ConfigError(
                f"system.{field}", f"a MuJoCo setting; {sy.name!r} is a function black box, leave it unset"
            )
    if sy.backend != "auto":
        raise ConfigError("system.backend", f"{sy.name!r} is a function black box: valid: auto")
