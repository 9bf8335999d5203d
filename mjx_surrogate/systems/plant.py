"""Plants that differ from the model a controller was built on (the mismatch of an MPC episode).

A plant is a :class:`System` whose step the controller does not know: it only measures the
state the plant reaches. A plant is written as text, ``"model"`` (the controller's own
system) or comma-separated changes ``NAME=VALUE``:

- on a MuJoCo model, scale factors applied to the compiled model (kept as a compiled file
  so that a run folder can replay the episode on it):
  ``mass`` (every body's mass and rotational inertia: a heavier robot of the same shape),
  ``length`` (every body's frame offsets, centre of mass, joint anchors, geoms and sites;
  masses kept, rotational inertias times the square: the same shapes, longer; refused
  where a moving body has a mesh or height-field geom, whose shape would stay),
  ``damping`` (every joint's damping; refused where the model has none) and ``gravity``;
- on a function black box, keyword arguments of the function that builds it (the
  registered ``make_system``, or the user's entry when it is a function), e.g. Lorenz's
  ``rho=30`` or Burgers' ``viscosity=0.02``: the same sizes and control period, other
  parameters.
"""

from __future__ import annotations

import copy
import dataclasses
import inspect
import math
import os

import mujoco
import numpy as np

from mjx_surrogate.errors import ConfigError
from mjx_surrogate.systems.function import FunctionSystem
from mjx_surrogate.systems.system import System, build_system

FIELD = "mpc.plants"
MODEL = "model"
MUJOCO_CHANGES = ("mass", "length", "damping", "gravity")
Changes = tuple[tuple[str, float], ...]
_MESHLIKE = (mujoco.mjtGeom.mjGEOM_MESH, mujoco.mjtGeom.mjGEOM_SDF, mujoco.mjtGeom.mjGEOM_HFIELD)


def parse_plant(text: str, field: str = FIELD) -> Changes:
    """``"model"`` -> (); ``"mass=1.5,damping=2"`` -> (("mass", 1.5), ("damping", 2.0));
    ConfigError naming ``field`` for anything else."""
    if not isinstance(text, str):
        raise ConfigError(field, f"a plant is text, 'model' or NAME=VALUE[,NAME=VALUE...], got {text!r}")
    if text.strip() == MODEL:
        return ()
    out = []
    for part in text.split(","):
        name, sep, value = (s.strip() for s in part.partition("="))
        try:
            v = float(value)
        except ValueError:
            v = math.nan
        if not sep or not name.isidentifier() or not math.isfinite(v):
            raise ConfigError(
                field, f"{text!r}: a plant is 'model' or NAME=VALUE[,NAME=VALUE...] with finite values"
            )
        if name in dict(out):
            raise ConfigError(field, f"{text!r} changes {name} twice")
        out.append((name, v))
    return tuple(out)


def plant_label(changes: Changes) -> str:
    """The plant's name in tables and metrics: ``model`` or ``mass=1.5,damping=2``."""
    return ",".join(f"{n}={v:g}" for n, v in changes) or MODEL


def plant_slug(changes: Changes) -> str:
    """The plant's name in file names: ``model`` or ``mass1.5_damping2``."""
    return "_".join(f"{n}{v:g}" for n, v in changes) or MODEL


def check_mujoco_changes(model: mujoco.MjModel, changes: Changes, text: str, field: str = FIELD) -> None:
    """ConfigError unless every change applies to ``model`` (before any compile)."""
    for name, v in changes:
        if name not in MUJOCO_CHANGES:
            raise ConfigError(
                field, f"{text!r}: a MuJoCo plant changes {', '.join(MUJOCO_CHANGES)}; got {name!r}"
            )
        if not v > 0:
            raise ConfigError(field, f"{text!r}: {name} is a scale factor, > 0; got {v:g}")
        if name == "damping" and not np.any(model.dof_damping):
            raise ConfigError(field, f"{text!r}: the model's joints have no damping to scale")
        if name == "length" and np.any(np.isin(model.geom_type[model.geom_bodyid > 0], _MESHLIKE)):
            raise ConfigError(
                field, f"{text!r}: length scales primitive geoms; a moving body has a mesh or height field"
            )


def changed_model(model: mujoco.MjModel, changes: Changes) -> mujoco.MjModel:
    """A copy of ``model`` with ``changes`` (scale factors of :data:`MUJOCO_CHANGES`) applied
    to the bodies below the world; derived constants (subtree masses...) recomputed."""
    check_mujoco_changes(model, changes, plant_label(changes))
    m = copy.deepcopy(model)
    for name, s in changes:
        if name == "mass":
            m.body_mass[1:] *= s
            m.body_inertia[1:] *= s
        elif name == "length":
            m.body_pos[1:] *= s
            m.body_ipos[1:] *= s
            m.body_inertia[1:] *= s * s
            m.jnt_pos[:] *= s
            moving = m.geom_bodyid > 0
            for arr in (m.geom_pos, m.geom_size, m.geom_rbound, m.geom_aabb):
                arr[moving] *= s
            sites = m.site_bodyid > 0
            m.site_pos[sites] *= s
            m.site_size[sites] *= s
        elif name == "damping":
            m.dof_damping[:] *= s
        else:  # gravity
            m.opt.gravity[:] *= s
    mujoco.mj_setConst(m, mujoco.MjData(m))
    return m


def builder_keywords(build) -> tuple[str, ...]:
    """The keyword parameters of a function that builds a black box (none for a built one)."""
    if not callable(build):
        return ()
    try:
        params = inspect.signature(build).parameters.values()
    except (TypeError, ValueError):
        return ()
    kinds = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
    return tuple(p.name for p in params if p.kind in kinds)


def check_function_changes(build, changes: Changes, text: str, name: str, field: str = FIELD) -> None:
    """ConfigError unless every change is a keyword of ``build``, the function that builds
    the function black box ``name``."""
    words = builder_keywords(build)
    for key, _ in changes:
        if key not in words:
            valid = ", ".join(words) if words else "none: it is given built, not as a function"
            raise ConfigError(field, f"{text!r}: {name}'s parameters are {valid}; got {key!r}")


def same_interface(system, plant, text: str, field: str = FIELD) -> None:
    """ConfigError unless ``plant`` has ``system``'s state and control sizes and period."""
    for attr in ("nx", "nu", "dt"):
        a, b = getattr(system, attr), getattr(plant, attr)
        if not np.isclose(float(a), float(b)):
            raise ConfigError(field, f"{text!r} changes {attr} ({a} -> {b}); a plant keeps the model's")


def function_plant(system, build, changes: Changes, text: str) -> FunctionSystem:
    """``build(**changes)``: the function black box ``system`` with other parameters, checked
    to keep its sizes and control period."""
    check_function_changes(build, changes, text, system.name)
    try:
        plant = build(**dict(changes))
    except ConfigError:
        raise
    except BaseException as exc:  # the user's code: one line, never a traceback
        msg = " ".join(str(exc).split())[:200]
        what = f"{text!r}: building {system.name} raised {type(exc).__name__}: {msg}"
        raise ConfigError(FIELD, what) from None
    if not isinstance(plant, FunctionSystem):
        raise ConfigError(FIELD, f"{text!r}: building {system.name} gave a {type(plant).__name__}")
    same_interface(system, plant, text)
    return dataclasses.replace(plant, name=f"{system.name}[{plant_label(changes)}]", source=system.source)


def mujoco_plant(system: System, changes: Changes, path: str) -> System:
    """``system``'s MuJoCo model with ``changes``, written to ``path`` (a compiled ``.mjb``)
    and simulated by native MuJoCo with the same control step."""
    mujoco.mj_saveModel(changed_model(system.mj_model, changes), path, None)
    return build_system(f"{system.name}[{plant_label(changes)}]", None, system.substeps, "native", path=path)


def check_plant(system, text: str, build=None) -> Changes:
    """The changes ``text`` names, checked against ``system`` (ConfigError naming
    mpc.plants otherwise, before any compile); ``build``: a function black box's builder."""
    changes = parse_plant(text)
    if changes and system.mj_model is not None:
        check_mujoco_changes(system.mj_model, changes, text)
    elif changes:
        function_plant(system, build, changes, text)
    return changes


def make_plant(system, text: str, folder: str, build=None):
    """The plant ``text`` names: ``system`` itself for "model"; a MuJoCo plant written to
    ``folder/plant_<slug>.mjb`` for replays; a function black box rebuilt by ``build``."""
    changes = check_plant(system, text, build)
    if not changes:
        return system
    if system.mj_model is not None:
        return mujoco_plant(system, changes, os.path.join(folder, f"plant_{plant_slug(changes)}.mjb"))
    return function_plant(system, build, changes, text)
