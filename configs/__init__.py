"""Presets: one module per preset, each defining ``CONFIG`` (``python -m experiments.run NAME``)."""

from __future__ import annotations

import importlib
import pkgutil


def names() -> list[str]:
    """Every preset's name."""
    return sorted(m.name for m in pkgutil.iter_modules(__path__) if not m.name.startswith("_"))


def load(name: str):
    """The ``CONFIG`` of preset ``name`` (a :class:`mjx_surrogate.config.Config`)."""
    return importlib.import_module(f"{__name__}.{name}").CONFIG
