"""Presets: one module per preset, each defining ``CONFIG`` (``python -m experiments.run NAME``)."""

from __future__ import annotations

import importlib
import pkgutil


def names() -> list[str]:
    """Every preset's name."""
    return sorted(m.name for m in pkgutil.iter_modules(__path__) if not m.name.startswith("_"))


def load(name: str):
    """The ``CONFIG`` of preset ``name`` (a :class:`mjx_surrogate.runs.config.Config`)."""
    return importlib.import_module(f"{__name__}.{name}").CONFIG


def preset(**sections: dict):
    """A preset as data: the default :class:`mjx_surrogate.runs.config.Config` with the fields
    each keyword section states (as :func:`derive` takes them)."""
    from mjx_surrogate.runs.config import Config

    return _changed(Config(), sections)


def derive(parent: str, **sections: dict):
    """Preset ``parent``'s config with the changes a derived preset states, and nothing else:
    each keyword is a section of :class:`mjx_surrogate.runs.config.Config` mapping its fields
    to new values, a nested section's field written with a dot (``surrogate={"mlp.epochs":
    50}``). An unknown section or field raises, as a typo must not pass unseen."""
    return _changed(load(parent), sections)


def _changed(cfg, sections: dict):
    for section, changes in sections.items():
        for path, value in changes.items():
            cfg = _replaced(cfg, (section, *path.split(".")), value)
    return cfg


def _replaced(obj, path: tuple, value):
    import dataclasses

    names = {f.name for f in dataclasses.fields(obj)}
    if path[0] not in names:
        raise KeyError(f"{type(obj).__name__} has no field {path[0]!r}; valid: {', '.join(sorted(names))}")
    if len(path) > 1:
        value = _replaced(getattr(obj, path[0]), path[1:], value)
    return dataclasses.replace(obj, **{path[0]: value})
