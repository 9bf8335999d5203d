"""Plants that differ from the model a controller was built on (the mismatch of an MPC episode).

A plant is a :class:`System` whose step the controller does not know: it only measures the
state the plant reaches. Here: the model's compiled MuJoCo model with every body's mass
and rotational inertia scaled (a heavier or lighter robot of the same shape), kept as a
compiled file so a run folder can replay the episode on it.
"""

from __future__ import annotations

import copy

import mujoco

from mjx_surrogate.systems.system import System, build_system


def mass_scaled_model(model: mujoco.MjModel, scale: float) -> mujoco.MjModel:
    """A copy of ``model`` whose bodies (the world excepted) have ``scale`` times their mass
    and rotational inertia; derived constants (subtree masses...) recomputed."""
    if not scale > 0:
        raise ValueError(f"scale must be > 0, got {scale}")
    m = copy.deepcopy(model)
    m.body_mass[1:] *= scale
    m.body_inertia[1:] *= scale
    mujoco.mj_setConst(m, mujoco.MjData(m))
    return m


def mass_scaled_plant(system: System, scale: float, path: str) -> System:
    """``system``'s MuJoCo model with masses and inertias times ``scale``, written to
    ``path`` (a compiled ``.mjb``) and simulated by native MuJoCo with the same control
    step (ValueError for a function black box: it has no masses)."""
    if getattr(system, "mj_model", None) is None:
        raise ValueError(f"{system.name} is a function black box: it has no masses to scale")
    mujoco.mj_saveModel(mass_scaled_model(system.mj_model, scale), path, None)
    return build_system(f"{system.name}_mass_x{scale:g}", None, system.substeps, "native", path=path)
