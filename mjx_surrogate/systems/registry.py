"""Registry of systems, built from one module per system, plus the user's MJCF.

A system module (``pendulum.py``, ``cartpole.py``, ``fish.py``, ``swimmer.py``) holds its
MJCF (``xml``), its ``default_config()`` and its task presets (``TASKS``). A new system is
one such module plus one :func:`register_system` call (docs/extending.md); a family with a
size in its name (``swimmer<N>``) is registered with a pattern. A black box that is a
function (``lorenz.py``, ``f8.py``: ``make_system()`` and ``TASKS``) is registered with
:func:`register_function_system`, a family of them with a size in the name (the PDEs
``burgers<N>``, ``allen_cahn<N>``, ``allen_cahn2d<N>``) with
:func:`register_function_family`; a user's function is named by ``system.entry``
(``system.name = "python"``, :mod:`.entry`).
"""

from __future__ import annotations

import functools
import os
import re
from types import ModuleType
from typing import Any, Callable

from jax.sharding import Mesh

from mjx_surrogate.errors import ConfigError
from mjx_surrogate.systems import (
    allen_cahn,
    burgers,
    cartpole,
    f8,
    fish,
    hydrax_tasks,
    lorenz,
    pendulum,
    swimmer,
)
from mjx_surrogate.systems.function import FunctionSystem, on_mesh
from mjx_surrogate.systems.spec import SystemDefaults
from mjx_surrogate.systems.system import System, build_system
from mjx_surrogate.tasks import TaskPreset

_SYSTEMS: dict[str, Callable[[], SystemDefaults]] = {}
_FAMILIES: dict[str, tuple[re.Pattern, Callable[[int], SystemDefaults]]] = {}
_TASKS: dict[str, TaskPreset] = {}
_FUNCTIONS: dict[str, Callable[[], FunctionSystem]] = {}
_FUNCTION_FAMILIES: dict[str, tuple[re.Pattern, Callable[[int], FunctionSystem]]] = {}
USER_FUNCTION = "python"  # system.name of a user's function, named by system.entry


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


def register_function_system(
    name: str, make: Callable[[], FunctionSystem], tasks: dict[str, TaskPreset] | None = None
) -> None:
    """Register a black box given as a function (``make()`` builds it) and its presets."""
    _FUNCTIONS[name] = make
    _TASKS.update(tasks or {})


def register_function_family(
    label: str,
    pattern: str,
    make: Callable[[Any], FunctionSystem],
    tasks: dict[str, TaskPreset] | None = None,
    parse: Callable[[str], Any] = int,
) -> None:
    """Register function black boxes named by ``pattern``, a regular expression with one
    group: ``make(parse(group))`` builds one. The default reads a size (the grid of a PDE,
    ``burgers256``); ``parse=str`` passes the text itself (an environment's id: a kind of
    black box, docs/extending.md)."""
    _FUNCTION_FAMILIES[label] = (re.compile(pattern), make, parse)
    _TASKS.update(tasks or {})


def _function_family(name: str) -> tuple[Callable[[Any], FunctionSystem], Any] | None:
    for pattern, make, parse in _FUNCTION_FAMILIES.values():
        if m := pattern.match(name):
            return make, parse(m.group(1))
    return None


def is_function_system(name: str) -> bool:
    """Whether ``system.name`` names a function black box (registered, or the user's)."""
    return name in _FUNCTIONS or name == USER_FUNCTION or _function_family(name) is not None


def make_function_system(name: str, mesh: Mesh | None = None) -> FunctionSystem:
    """A registered function black box, its batched work spread over ``mesh``
    (:func:`~.function.on_mesh`), built once per process and mesh: the same name and mesh
    give the same object, so that programs jitted on it are reused."""
    if name not in _FUNCTIONS and _function_family(name) is None:
        raise ConfigError("system.name", f"unknown system {name!r}; valid: {', '.join(system_names())}")
    return _built_function(name, mesh)


def function_builder(name: str) -> Callable[..., FunctionSystem]:
    """The function that builds the registered function black box ``name`` (its size bound
    for a family): called with keyword arguments, another instance of it (a plant)."""
    if name in _FUNCTIONS:
        return _FUNCTIONS[name]
    if (found := _function_family(name)) is None:
        raise ConfigError("system.name", f"unknown system {name!r}; valid: {', '.join(system_names())}")
    make, size = found
    return functools.partial(make, size)


@functools.lru_cache(maxsize=None)
def _built_function(name: str, mesh: Mesh | None = None) -> FunctionSystem:
    if mesh is not None:
        return on_mesh(_built_function(name), mesh)
    if name in _FUNCTIONS:
        return _FUNCTIONS[name]()
    make, size = _function_family(name)
    try:
        return make(size)
    except ValueError as e:
        raise ConfigError("system.name", str(e)) from None


def _register_module(name: str, module: ModuleType) -> None:
    register_system(name, module.default_config, module.TASKS)


for _name, _module in (("pendulum", pendulum), ("cartpole", cartpole), ("fish", fish)):
    _register_module(_name, _module)
register_system("hydrax_pendulum", hydrax_tasks.pendulum_config, hydrax_tasks.PENDULUM_TASKS)
register_system("hydrax_cartpole", hydrax_tasks.cartpole_config, hydrax_tasks.CARTPOLE_TASKS)
register_family(
    "swimmer<N> (N >= 2, e.g. swimmer6)", r"^swimmer(\d+)$", swimmer.default_config, swimmer.TASKS
)
for _name, _module in (("lorenz", lorenz), ("f8", f8)):
    register_function_system(_name, _module.make_system, _module.TASKS)
register_function_family(
    "burgers<N> (N >= 8 cells, e.g. burgers64)", r"^burgers(\d+)$", burgers.make_system, burgers.TASKS
)
register_function_family(
    "allen_cahn<N> (N >= 8 cells, e.g. allen_cahn64)",
    r"^allen_cahn(\d+)$",
    allen_cahn.make_system,
    allen_cahn.TASKS,
)
register_function_family(
    "allen_cahn2d<N> (N x N cells, N >= 8, e.g. allen_cahn2d16)",
    r"^allen_cahn2d(\d+)$",
    lambda n: allen_cahn.make_system(n, dims=2),
)


def system_names() -> tuple[str, ...]:
    return (
        tuple(_SYSTEMS)
        + tuple(_FAMILIES)
        + tuple(_FUNCTIONS)
        + tuple(_FUNCTION_FAMILIES)
        + ("mjcf", USER_FUNCTION)
    )


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
    if is_function_system(name):
        raise ConfigError("system.name", f"{name!r} is a function black box, not a MuJoCo model")
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
    model_copy: str | None = None,
) -> System:
    """Build a system from the user's MJCF file (includes and meshes resolved next to it).
    ``auto`` picks ``native``: it runs every MuJoCo feature and won on 2 cores for all but
    the smallest models we measured. ``model_copy``: a compiled copy of the model (a run
    folder's ``model.mjb``) to simulate instead of the file, which then need not exist."""
    field = "system.mjcf_path" if model_copy is None else "system.model_copy"
    if not os.path.isfile(model_copy or path):
        raise ConfigError(field, f"no such file {model_copy or path!r}; give a path to an MJCF .xml")
    name = os.path.splitext(os.path.basename(path))[0]
    return build_system(
        name,
        None,
        substeps,
        "native" if backend == "auto" else backend,
        timestep,
        native_threads,
        field=field,
        path=model_copy or path,
        mesh=mesh,
    )
