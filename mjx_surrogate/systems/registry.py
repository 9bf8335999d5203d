"""Registry of systems, built from one module per system, plus the user's MJCF.

A system module (``pendulum.py``, ``cartpole.py``, ``fish.py``, ``swimmer.py``) holds its
MJCF (``xml``), its ``default_config()`` and its task presets (``TASKS``). A new system is
one such module plus one :func:`register_system` call (docs/extending.md); a family with a
size in its name (``swimmer<N>``) is registered with a pattern.
"""

from __future__ import annotations

import functools
import os
import re
from types import ModuleType
from typing import Callable

from jax.sharding import Mesh

from mjx_surrogate.errors import ConfigError
from mjx_surrogate.systems import cartpole, fish, pendulum, swimmer
from mjx_surrogate.systems.spec import SystemDefaults
from mjx_surrogate.systems.system import System, build_system
from mjx_surrogate.tasks import TaskPreset

_SYSTEMS: dict[str, Callable[[], SystemDefaults]] = {}
_FAMILIES: dict[str, tuple[re.Pattern, Callable[[int], SystemDefaults]]] = {}
_TASKS: dict[str, TaskPreset] = {}


def register_system(
    name: str, default_config: Callable[[], SystemDefaults], tasks: dict[str, TaskPreset] | None = None
) -> None:
    """Register a system ``name`` and its task presets."""
    _SYSTEMS[name] = default_config
    _TASKS.update(tasks or {})


def register_family(
    label: str,
    pattern: str,
    default_config: Callable[[int], SystemDefaults],
    tasks: dict[str, TaskPreset] | None = None,
) -> None:
    """Register sized systems whose name matches ``pattern`` (one integer group, >= 2)."""
    _FAMILIES[label] = (re.compile(pattern), default_config)
    _TASKS.update(tasks or {})


def _register_module(name: str, module: ModuleType) -> None:
    register_system(name, module.default_config, module.TASKS)


for _name, _module in (("pendulum", pendulum), ("cartpole", cartpole), ("fish", fish)):
    _register_module(_name, _module)
register_family(
    "swimmer<N> (N >= 2, e.g. swimmer6)", r"^swimmer(\d+)$", swimmer.default_config, swimmer.TASKS
)


def system_names() -> tuple[str, ...]:
    return tuple(_SYSTEMS) + tuple(_FAMILIES) + ("mjcf",)


def task_presets() -> dict[str, TaskPreset]:
    """Every registered task preset by name."""
    return dict(_TASKS)


def preset_fits(preset: TaskPreset, system_name: str) -> bool:
    """Whether a preset belongs to the system (``family*`` matches every size)."""
    if preset.system.endswith("*"):
        return system_name.startswith(preset.system[:-1])
    return preset.system == system_name


def default_config(name: str) -> SystemDefaults:
    """Defaults of a registered system; raises ConfigError for an unknown name."""
    if name in _SYSTEMS:
        return _SYSTEMS[name]()
    for pattern, make in _FAMILIES.values():
        match = pattern.match(name)
        if match and int(match.group(1)) >= 2:
            return make(int(match.group(1)))
    raise ConfigError("system.name", f"unknown system {name!r}; valid: {', '.join(system_names())}")


def make_system(
    name: str,
    backend: str = "auto",
    substeps: int | None = None,
    timestep: float | None = None,
    native_threads: int | None = None,
    mesh: Mesh | None = None,
) -> System:
    """Build a registered system (``pendulum``, ``cartpole``, ``fish``, ``swimmerN``),
    its batched work spread over ``mesh`` (:mod:`mjx_surrogate.sharding`; None: one device).

    ``backend="auto"`` takes the measured faster backend for this system on the CPU. The
    same arguments (and precision) give the same :class:`System` object, so programs
    jitted on it are reused rather than compiled again (a System is immutable).
    """
    import jax

    d = default_config(name)
    return _built(
        name,
        d.backend if backend == "auto" else backend,
        substeps if substeps is not None else d.substeps,
        timestep,
        native_threads,
        bool(jax.config.jax_enable_x64),
        mesh,
    )


@functools.lru_cache(maxsize=32)
def _built(
    name: str,
    backend: str,
    substeps: int,
    timestep: float | None,
    native_threads: int | None,
    x64: bool,
    mesh: Mesh | None,
) -> System:
    xml = default_config(name).xml()
    return build_system(
        name, xml, substeps, backend, timestep, native_threads, field="system.name", mesh=mesh
    )


def from_mjcf(
    path: str,
    backend: str = "auto",
    substeps: int = 1,
    timestep: float | None = None,
    native_threads: int | None = None,
    mesh: Mesh | None = None,
) -> System:
    """Build a system from the user's MJCF file (includes and meshes resolved next to it).
    ``auto`` picks ``native``: it runs every MuJoCo feature and won on 2 cores for all but
    the smallest models we measured."""
    if not os.path.isfile(path):
        raise ConfigError("system.mjcf_path", f"no such file {path!r}; give a path to an MJCF .xml")
    name = os.path.splitext(os.path.basename(path))[0]
    return build_system(
        name,
        None,
        substeps,
        "native" if backend == "auto" else backend,
        timestep,
        native_threads,
        field="system.mjcf_path",
        path=path,
        mesh=mesh,
    )
