"""Settings an extension brings with it (docs/extending.md).

An identification scheme, a model strategy, a surrogate kind, an experiment kind or a
planner may declare ``settings``:
a frozen dataclass instance holding its defaults. A config keeps the values given in
``Config.extensions`` under ``"<section>.<name>"``: ``sysid.<scheme>``, ``solver.<strategy>``,
``surrogate.<kind>``, ``experiment.<kind>`` or ``mpc.<planner>``, each a dataclass instance or a mapping of
some of its fields (as a run's ``config.json`` writes it). The command line sets a field
as ``--sysid.<scheme>.<field> VALUE``: it parses a Config type generated from these
declarations (:func:`with_declared`), one field per extension in its section. Before any
compile every field is checked against its declared type, numbers must be finite, and the
settings' own ``check()`` (if any) raises ConfigError(field name, message) for values it
refuses.
"""

from __future__ import annotations

import dataclasses
import math
import typing
from typing import Any

from mjx_surrogate.control.model_strategies import MODEL_STRATEGIES
from mjx_surrogate.control.planners import PLANNERS
from mjx_surrogate.errors import ConfigError
from mjx_surrogate.identification.sysid import SCHEMES
from mjx_surrogate.runs.config import from_dict
from mjx_surrogate.runs.experiment_kinds import EXPERIMENTS
from mjx_surrogate.surrogates.registry import SURROGATES


def declared() -> dict[str, Any]:
    """``"<section>.<name>"`` -> the settings' defaults, for every registered extension
    that declares settings."""
    out = {}
    registries = (
        ("sysid", SCHEMES),
        ("solver", MODEL_STRATEGIES),
        ("surrogate", SURROGATES),
        ("experiment", EXPERIMENTS),
        ("mpc", PLANNERS),
    )
    for section, registry in registries:
        for name, entry in registry.items():
            if getattr(entry, "settings", None) is not None:
                out[f"{section}.{name}"] = entry.settings
    return out


def _defaults(key: str) -> Any:
    found = declared()
    if key not in found:
        valid = ", ".join(found) or "none registered"
        raise ConfigError(
            f"extensions.{key}", f"no registered extension declares settings here; valid: {valid}"
        )
    return found[key]


def settings_from(defaults: Any, value: Any, field: str) -> Any:
    """The settings ``value`` (an instance, or a mapping of some fields) over ``defaults``,
    every field checked (type, finite numbers, the settings' ``check()``)."""
    cls = type(defaults)
    if isinstance(value, cls):
        value = dataclasses.asdict(value)
    if not isinstance(value, dict):
        raise ConfigError(
            field, f"expected {cls.__name__} or a mapping of its fields, got {type(value).__name__}"
        )
    given = from_dict(cls, value, field)  # field names and types
    merged = dataclasses.replace(defaults, **{k: getattr(given, k) for k in value})
    for f in dataclasses.fields(merged):
        v = getattr(merged, f.name)
        if isinstance(v, float) and not math.isfinite(v):
            raise ConfigError(f"{field}.{f.name}", f"must be a finite number, got {v}")
    check = getattr(merged, "check", None)
    if check is not None:
        try:
            check()
        except ConfigError as e:
            raise ConfigError(f"{field}.{e.field}", str(e).removeprefix(f"{e.field}: ")) from None
    return merged


def settings_of(config: Any, section: str, name: str) -> Any:
    """The settings of extension ``name`` of ``section`` for this config: its declared
    defaults with the config's values over them."""
    key = f"{section}.{name}"
    defaults = _defaults(key)
    return settings_from(defaults, config.extensions.get(key, defaults), key)


def check_extensions(config: Any) -> None:
    """Every entry of ``config.extensions`` belongs to a registered extension with
    settings, one the config uses (a planner's may stand unused: a preset keeps each of
    its planners' settings when a run picks fewer), and holds valid values."""
    for key, value in config.extensions.items():
        section, _, name = key.partition(".")
        settings_from(_defaults(key), value, key)
        if section == "mpc":
            continue
        chosen = {
            "sysid": (config.sysid.scheme, config.mpc.sysid.scheme),
            "solver": (config.solver.model_strategy,),
            "surrogate": config.surrogate.kinds,
            "experiment": (config.experiment.kind,),
            "mpc": config.mpc.controllers,
        }[section]
        if name not in chosen:
            raise ConfigError(
                key, f"settings of {name!r}, which this config does not use ({section}: {', '.join(chosen)})"
            )


def with_declared(config: Any) -> Any:
    """``config`` as an instance of a Config type generated from the declarations: each
    section that registered extensions declare settings in gains a field per extension
    (``sysid.<scheme>``, ``solver.<strategy>``, ``surrogate.<kind>``, ``experiment.<kind>``,
    ``mpc.<planner>``) holding its settings (the config's, over the defaults), so that a
    command-line parser reads ``--sysid.<scheme>.<field>`` as it reads every built-in field.
    :func:`without_declared` takes them back out."""
    extra: dict[str, list] = {}
    for key, defaults in declared().items():
        section, _, name = key.partition(".")
        current = settings_from(defaults, config.extensions.get(key, defaults), key)
        field = dataclasses.field(default_factory=lambda v=current: v)
        extra.setdefault(section, []).append((name, type(defaults), field))
    sections, types_ = {}, []
    for section, fields in extra.items():
        base = getattr(config, section)
        cls = dataclasses.make_dataclass(type(base).__name__, fields, bases=(type(base),), frozen=True)
        cls.__module__ = type(base).__module__
        sections[section] = cls(**_values(base), **{n: f.default_factory() for n, _, f in fields})
        types_.append((section, cls, dataclasses.field(default_factory=lambda v=sections[section]: v)))
    if not types_:
        return config
    cls = dataclasses.make_dataclass(type(config).__name__, types_, bases=(type(config),), frozen=True)
    cls.__module__ = type(config).__module__
    return cls(**{**_values(config), **sections})


def without_declared(parsed: Any, config_type: type, given: set[str]) -> Any:
    """The ``config_type`` instance of a :func:`with_declared` config; the extension
    settings that ``given`` names (those set on the command line) replace the config's
    in ``extensions``, the others stay as the config had them."""
    extensions, sections = dict(parsed.extensions), {}
    hints = typing.get_type_hints(config_type)
    for f in dataclasses.fields(config_type):
        value, base_type = getattr(parsed, f.name), hints[f.name]
        if f.name == "extensions" or type(value) is base_type:
            continue
        own = _values(value, base_type)
        sections[f.name] = base_type(**own)
        for g in dataclasses.fields(value):
            key = f"{f.name}.{g.name}"
            if g.name not in own and key in given:
                extensions[key] = getattr(value, g.name)
    return config_type(**{**_values(parsed, config_type), **sections, "extensions": extensions})


def _values(obj: Any, cls: type | None = None) -> dict:
    """The fields of ``cls`` (default: obj's type) of ``obj``, unconverted."""
    return {f.name: getattr(obj, f.name) for f in dataclasses.fields(cls or type(obj))}
