"""A user's black box named by an entry point: ``pkg.module:make_system`` or
``path/to/file.py:make_system`` (``system.name = "python"``, ``system.entry``).

The attribute is a :class:`~mjx_surrogate.systems.function.FunctionSystem` or a function of
no arguments returning one (``from_numpy`` or ``from_jax`` around the user's step). The
defining file is the system's ``source``: a run folder keeps a copy and its SHA-256, and a
replay refuses to run when the file has changed since (:func:`source_digest`). Every
failure is a :class:`~mjx_surrogate.errors.ConfigError` naming ``system.entry``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib
import importlib.util
import os
import sys

from mjx_surrogate.errors import ConfigError
from mjx_surrogate.systems.function import FunctionSystem

FIELD = "system.entry"
FORM = "MODULE:ATTRIBUTE or FILE.py:ATTRIBUTE"


def _import(target: str):
    """The module named by a dotted name or a .py path."""
    if target.endswith(".py"):
        if not os.path.isfile(target):
            raise ConfigError(FIELD, f"no such file {target!r} ({FORM})")
        name = "mjx_surrogate_user_" + hashlib.sha256(os.path.abspath(target).encode()).hexdigest()[:12]
        spec = importlib.util.spec_from_file_location(name, target)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module  # dataclasses and pickling look modules up by name
        spec.loader.exec_module(module)
        return module
    return importlib.import_module(target)


def load_entry(entry: str) -> FunctionSystem:
    """The black box that ``entry`` names, its ``source`` set to the defining file."""
    made, module = _attribute(entry)
    if callable(made) and not isinstance(made, FunctionSystem):
        try:
            made = made()
        except BaseException as exc:
            msg = " ".join(str(exc).split())[:200]
            raise ConfigError(FIELD, f"{entry}() raised {type(exc).__name__}: {msg}") from None
    if not isinstance(made, FunctionSystem):
        raise ConfigError(
            FIELD,
            f"{entry} gave a {type(made).__name__}, not a FunctionSystem "
            "(build one with mjx_surrogate.systems.from_numpy or from_jax)",
        )
    source = getattr(module, "__file__", None)
    return dataclasses.replace(made, source=os.path.abspath(source) if source else None)


def entry_builder(entry: str):
    """The function ``entry`` names (None where it names a built FunctionSystem)."""
    made, _ = _attribute(entry)
    return made if callable(made) and not isinstance(made, FunctionSystem) else None


def _attribute(entry: str):
    """(the attribute ``entry`` names, its module); ConfigError naming system.entry."""
    target, sep, attr = entry.rpartition(":")
    if not sep or not target or not attr.isidentifier():
        raise ConfigError(FIELD, f"{entry!r} is not {FORM}")
    try:
        module = _import(target)
    except ConfigError:
        raise
    except BaseException as exc:  # the user's code: one line, never a traceback
        msg = " ".join(str(exc).split())[:200]
        raise ConfigError(FIELD, f"importing {target!r} raised {type(exc).__name__}: {msg}") from None
    if not hasattr(module, attr):
        raise ConfigError(FIELD, f"{target!r} has no attribute {attr!r}")
    return getattr(module, attr), module


def entry_source(entry: str) -> str | None:
    """The file that defines ``entry``'s module, found without running it."""
    target = entry.rpartition(":")[0]
    if target.endswith(".py"):
        return os.path.abspath(target) if os.path.isfile(target) else None
    try:
        spec = importlib.util.find_spec(target)
    except (ImportError, ValueError):
        return None
    return spec.origin if spec is not None and spec.origin and os.path.isfile(spec.origin) else None


def source_digest(path: str | None) -> str | None:
    """SHA-256 of the file at ``path`` (None without one)."""
    if not path or not os.path.isfile(path):
        return None
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()
