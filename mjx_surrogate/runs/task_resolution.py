"""Task resolution: a TaskConfig plus a system -> every task field filled and checked.

Sources, in order: the field itself, a keyframe of the model, the task preset, the
model (actuator ctrlrange for the control limits, qpos0 for a custom or hold task's start;
the ``hold`` preset's goal, weights and control reference: ``model_defaults.hold_task``).
Every check raises :class:`~mjx_surrogate.errors.ConfigError` naming the field.
"""

from __future__ import annotations

from typing import Callable

import mujoco
import numpy as np

from mjx_surrogate.errors import ConfigError
from mjx_surrogate.moving_targets import target_motion
from mjx_surrogate.runs.config import TaskConfig, check_finite
from mjx_surrogate.runs.function_task import resolve_function_task
from mjx_surrogate.runs.model_defaults import control_weights, hold_controls, hold_task
from mjx_surrogate.runs.task_fields import (
    MAX_T,
    MODEL_PRESETS,
    limits_field,
    matrix_field,
    preset_fields,
    resolved_task_config,
    state_field,
)
from mjx_surrogate.systems import System
from mjx_surrogate.systems.black_box import BlackBox
from mjx_surrogate.systems.kinematics import make_points_fn, native_points_fn, point_ids
from mjx_surrogate.systems.system import state_labels
from mjx_surrogate.tasks import Task, make_task


def model_state(m: mujoco.MjModel, qpos, qvel=None, act=None) -> np.ndarray:
    """[qpos, qvel, act] with zero velocity and activation by default."""
    qvel = np.zeros(m.nv) if qvel is None else qvel
    act = np.zeros(m.na) if act is None else act
    return np.concatenate([qpos, qvel, act]).astype(float)


def keyframe(m: mujoco.MjModel, key: str, field: str) -> tuple[np.ndarray, np.ndarray]:
    """(state [nx], ctrl [nu]) of keyframe ``key`` (its name, or its index as digits)."""
    names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_KEY, i) or str(i) for i in range(m.nkey)]
    if key in names:
        i = names.index(key)
    elif key.isdigit() and int(key) < m.nkey:
        i = int(key)
    else:
        valid = ", ".join(names) if names else "the model has no keyframes"
        raise ConfigError(field, f"no keyframe {key!r}; valid: {valid}")
    return model_state(m, m.key_qpos[i], m.key_qvel[i], m.key_act[i]), np.array(m.key_ctrl[i], float)


def model_limits(m: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """The actuators' ctrlrange, +-inf where a control is not limited."""
    limited = m.actuator_ctrllimited.astype(bool)
    lo = np.where(limited, m.actuator_ctrlrange[:, 0], -np.inf)
    hi = np.where(limited, m.actuator_ctrlrange[:, 1], np.inf)
    return lo, hi


def geodesic_indices(m: mujoco.MjModel) -> tuple[tuple, tuple]:
    """(qpos indices of hinge joints, first qpos index of each ball/free quaternion)."""
    hinges, quats = [], []
    for j in range(m.njnt):
        a, kind = int(m.jnt_qposadr[j]), m.jnt_type[j]
        if kind == mujoco.mjtJoint.mjJNT_HINGE:
            hinges.append(a)
        elif kind == mujoco.mjtJoint.mjJNT_BALL:
            quats.append(a)
        elif kind == mujoco.mjtJoint.mjJNT_FREE:
            quats.append(a + 3)
    return tuple(hinges), tuple(quats)


def _points(system: System, tc: TaskConfig):
    if not tc.goals:
        return None
    ids = tuple(point_ids(system.mj_model, tc.goals))
    cache = system.once("points_fns", dict)  # one function per goal set
    if ids not in cache:  # native kinematics with a native simulator: nothing to compile
        make = native_points_fn if system.backend == "native" else make_points_fn
        cache[ids] = make(system.mj_model, list(ids))
    return cache[ids]


def _motion(system: System, goals) -> Callable | None:
    """The goals' moving targets (``moving_targets.target_motion``), one function per
    motion and control period (a task resolved twice compiles once)."""
    spec = tuple((tuple(g.velocity), g.orbit_radius, g.orbit_period, g.orbit_plane) for g in goals)
    cache = system.once("motion_fns", dict)
    key = (spec, float(system.dt))
    if key not in cache:
        cache[key] = target_motion(*zip(*spec), float(system.dt)) if spec else None
    return cache[key]


def resolve_task(tc: TaskConfig, system: BlackBox) -> tuple[TaskConfig, Task]:
    """Fill every task field (preset, keyframes, model) with shape and sign checks; returns
    the resolved TaskConfig (what config.json holds) and the Task. A function black box's
    task: :func:`mjx_surrogate.runs.function_task.resolve_function_task`."""
    if system.mj_model is None:
        return resolve_function_task(tc, system)
    m = system.mj_model
    base = preset_fields(tc, system)
    T = tc.T if tc.T is not None else base.get("T")
    if T is None:
        raise ConfigError("task.T", "required with task.preset='custom' (a positive integer)")
    if not 1 <= T <= MAX_T:
        raise ConfigError("task.T", f"horizon must be an integer in [1, {MAX_T}], got {T}")
    labels = state_labels(m)
    nx, nu = system.nx, system.nu
    key_x0 = key_goal = key_ctrl = None
    if tc.x0_keyframe is not None:
        key_x0, _ = keyframe(m, tc.x0_keyframe, "task.x0_keyframe")
        if tc.x0 is not None and (len(tc.x0) != len(key_x0) or not np.allclose(tc.x0, key_x0, atol=1e-12)):
            raise ConfigError("task.x0_keyframe", "give task.x0 or task.x0_keyframe, not both")
    if tc.goal_keyframe is not None:
        key_goal, key_ctrl = keyframe(m, tc.goal_keyframe, "task.goal_keyframe")
        if tc.x_goal is not None and (
            len(tc.x_goal) != len(key_goal) or not np.allclose(tc.x_goal, key_goal, atol=1e-12)
        ):
            raise ConfigError("task.goal_keyframe", "give task.x_goal or task.goal_keyframe, not both")
    custom = tc.preset in MODEL_PRESETS
    qpos0 = model_state(m, m.qpos0)
    x0 = state_field(
        tc, "x0", labels, key_x0 if key_x0 is not None else base.get("x0", qpos0 if custom else None)
    )
    u_min, u_max = limits_field(tc, *model_limits(m), base)
    if tc.preset == "hold":
        base = hold_task(m, x0, u_min, u_max)
    goal_default = key_goal if key_goal is not None else base.get("x_goal", x0 if tc.goals else None)
    x_goal = state_field(tc, "x_goal", labels, goal_default)
    if x_goal is None:
        raise ConfigError(
            "task.x_goal", f"required with task.preset='custom' ({nx} numbers, a goal_keyframe or task.goals)"
        )
    zeros = {"Q": np.zeros((nx, nx)), "Q_f": np.zeros((nx, nx))} if (custom and tc.goals) else {}
    Q, Q_f = matrix_field(tc, {**zeros, **base}, "Q", nx), matrix_field(tc, {**zeros, **base}, "Q_f", nx)
    R = matrix_field(tc, {"R": control_weights(u_min, u_max), **base} if custom else base, "R", nu)
    if tc.u_ref is not None:
        if len(tc.u_ref) != nu:
            raise ConfigError("task.u_ref", f"needs nu={nu} entries, got {len(tc.u_ref)}")
        check_finite("task.u_ref", tc.u_ref)
    if key_ctrl is not None:
        u_ref_default = key_ctrl
    elif "u_ref" in base:
        u_ref_default = base["u_ref"]
    else:  # a custom task: the controls that hold x0 (zero controls send servos to angle 0)
        u_ref_default = hold_controls(m, x0, u_min, u_max) if custom else np.zeros(nu)
    u_ref = np.asarray(tc.u_ref if tc.u_ref is not None else u_ref_default)
    state_error = tc.state_error or base.get("state_error", "geodesic")
    hinges, quats = geodesic_indices(m) if state_error in ("geodesic", "chordal") else ((), ())
    points = _points(system, tc)
    goals = tc.goals
    task = make_task(
        x0,
        x_goal,
        Q,
        Q_f,
        R,
        int(T),
        u_min,
        u_max,
        u_ref=u_ref,
        targets=[g.target for g in goals] if goals else None,
        weights=[g.weight for g in goals] if goals else None,
        final_weights=[g.final_weight for g in goals] if goals else None,
        points=points,
        motion=_motion(system, goals),
        hinges=hinges,
        quats=quats,
        chordal=state_error == "chordal",
        gauss_newton=tc.hessian == "gauss_newton",
    )
    return resolved_task_config(tc, T, x0, x_goal, Q, Q_f, R, u_min, u_max, u_ref, state_error), task
