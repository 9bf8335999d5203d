"""Registry of the paper's systems, each with its ``default_config()``, plus user MJCF."""

from __future__ import annotations

import os
import re
from typing import Callable, NamedTuple

from mjx_surrogate.errors import ConfigError
from mjx_surrogate.systems import models
from mjx_surrogate.systems.system import System, build_system


class SystemDefaults(NamedTuple):
    """Per-system defaults. ``backend`` is the faster one on a 2-core CPU, as measured
    by ``benchmarks/rollout.py`` (see docs/performance.md)."""

    xml: Callable[[], str]
    substeps: int
    backend: str


def pendulum_default() -> SystemDefaults:
    # dt 0.1 s per control step, as in D2C 2.0.
    return SystemDefaults(models.pendulum_xml, substeps=5, backend="mjx")


def cartpole_default() -> SystemDefaults:
    # dt 0.1 s per control step (D2C 2.0), 10 RK4 steps of 0.01 s.
    return SystemDefaults(models.cartpole_xml, substeps=10, backend="mjx")


def fish_default() -> SystemDefaults:
    # dm_control control step 0.04 s = 10 physics steps of 0.004 s.
    return SystemDefaults(models.fish_xml, substeps=10, backend="native")


def swimmer_default(n_links: int) -> SystemDefaults:
    # dm_control control step 0.03 s = 15 physics steps of 0.002 s.
    return SystemDefaults(lambda: models.swimmer_xml(n_links), substeps=15, backend="native")


_FIXED = {"pendulum": pendulum_default, "cartpole": cartpole_default, "fish": fish_default}
_SWIMMER = re.compile(r"^swimmer(\d+)$")
SYSTEM_NAMES = ("pendulum", "cartpole", "fish", "swimmer<N> (N >= 2, e.g. swimmer6)", "mjcf")


def default_config(name: str) -> SystemDefaults:
    """Defaults of a registered system; raises ConfigError for an unknown name."""
    if name in _FIXED:
        return _FIXED[name]()
    match = _SWIMMER.match(name)
    if match and int(match.group(1)) >= 2:
        return swimmer_default(int(match.group(1)))
    raise ConfigError("system.name", f"unknown system {name!r}; valid: {', '.join(SYSTEM_NAMES)}")


def make_system(name: str, backend: str = "auto", substeps: int | None = None,
                timestep: float | None = None, native_threads: int | None = None) -> System:
    """Build a registered system (``pendulum``, ``cartpole``, ``fish``, ``swimmerN``).

    ``backend="auto"`` takes the measured faster backend for this system on the CPU.
    """
    d = default_config(name)
    return build_system(name, d.xml(), substeps if substeps is not None else d.substeps,
                        d.backend if backend == "auto" else backend, timestep, native_threads,
                        field="system.name")


def from_mjcf(path: str, backend: str = "auto", substeps: int = 1,
              timestep: float | None = None, native_threads: int | None = None) -> System:
    """Build a system from the user's MJCF file. ``auto`` picks ``native``: it runs every
    MuJoCo feature and won on 2 cores for all but the smallest models we measured."""
    if not os.path.isfile(path):
        raise ConfigError("system.mjcf_path", f"no such file {path!r}; give a path to an MJCF .xml")
    with open(path) as f:
        xml = f.read()
    name = os.path.splitext(os.path.basename(path))[0]
    # MjSpec.from_string cannot resolve includes/meshes relative to the file, from_file can.
    cwd = os.getcwd()
    try:
        os.chdir(os.path.dirname(os.path.abspath(path)))
        return build_system(name, xml, substeps, "native" if backend == "auto" else backend,
                            timestep, native_threads, field="system.mjcf_path")
    finally:
        os.chdir(cwd)
