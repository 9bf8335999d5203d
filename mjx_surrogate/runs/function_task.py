"""Task resolution for a black box given as a function (no MuJoCo model behind it).

Sources, in order: the field itself, the task preset (``lorenz_switch``, ``f8_recovery``,
or one registered with the system), the system (its control limits). ``custom`` needs
x0, x_goal, T, Q and Q_f; R defaults to the weights of a MuJoCo custom task (inverse
squared half-ranges of the controls). What needs a MuJoCo model (keyframes, point goals,
the ``hold`` preset) is refused naming the field.
"""

from __future__ import annotations

import numpy as np

from mjx_surrogate.errors import ConfigError
from mjx_surrogate.runs.config import TaskConfig, check_finite
from mjx_surrogate.runs.model_defaults import control_weights
from mjx_surrogate.runs.task_fields import (
    MAX_T,
    limits_field,
    matrix_field,
    preset_fields,
    resolved_task_config,
    state_field,
)
from mjx_surrogate.systems import task_presets
from mjx_surrogate.systems.function import FunctionSystem
from mjx_surrogate.systems.registry import preset_fits
from mjx_surrogate.tasks import Task, make_task


def _own_presets(system: FunctionSystem) -> list[str]:
    return [n for n, p in task_presets().items() if preset_fits(p, system.name)]


def _refuse_mujoco_fields(tc: TaskConfig, system: FunctionSystem) -> None:
    what = f"{system.name!r} is a function black box, not a MuJoCo model"
    for field in ("x0_keyframe", "goal_keyframe"):
        if getattr(tc, field) is not None:
            raise ConfigError(
                f"task.{field}", f"a keyframe needs a MuJoCo model; {what}: give task.x0 / x_goal"
            )
    if tc.goals:
        raise ConfigError("task.goals", f"point goals need MuJoCo kinematics; {what}: use task.x_goal and Q")
    if tc.preset == "hold":
        valid = ", ".join(["custom"] + _own_presets(system))
        raise ConfigError("task.preset", f"'hold' keeps a MuJoCo model's start; {what}; valid: {valid}")


def resolve_function_task(tc: TaskConfig, system: FunctionSystem) -> tuple[TaskConfig, Task]:
    """Every task field filled and checked; returns the resolved TaskConfig and the Task."""
    _refuse_mujoco_fields(tc, system)
    base = preset_fields(tc, system)
    custom = tc.preset == "custom"
    T = tc.T if tc.T is not None else base.get("T")
    if T is None:
        raise ConfigError("task.T", "required with task.preset='custom' (a positive integer)")
    if not 1 <= T <= MAX_T:
        raise ConfigError("task.T", f"horizon must be an integer in [1, {MAX_T}], got {T}")
    labels = list(system.state_labels)
    x0 = state_field(tc, "x0", labels, base.get("x0"))
    x_goal = state_field(tc, "x_goal", labels, base.get("x_goal"))
    for name, v in (("x0", x0), ("x_goal", x_goal)):
        if v is None:
            raise ConfigError(
                f"task.{name}",
                f"required with task.preset='custom' ({system.nx} numbers [{', '.join(labels)}])",
            )
    u_min, u_max = limits_field(tc, np.asarray(system.u_min), np.asarray(system.u_max), base)
    Q, Q_f = matrix_field(tc, base, "Q", system.nx), matrix_field(tc, base, "Q_f", system.nx)
    R = matrix_field(tc, {"R": control_weights(u_min, u_max), **base} if custom else base, "R", system.nu)
    if tc.u_ref is not None:
        if len(tc.u_ref) != system.nu:
            raise ConfigError("task.u_ref", f"needs nu={system.nu} entries, got {len(tc.u_ref)}")
        check_finite("task.u_ref", tc.u_ref)
    u_ref = np.asarray(tc.u_ref if tc.u_ref is not None else base.get("u_ref", np.zeros(system.nu)), float)
    state_error = tc.state_error or base.get("state_error", "euclidean")
    hinges = tuple(a for a, _ in system.angle_pairs) if state_error in ("geodesic", "chordal") else ()
    chordal = state_error == "chordal"
    shape = dict(u_ref=u_ref, hinges=hinges, chordal=chordal, gauss_newton=tc.hessian == "gauss_newton")
    task = make_task(x0, x_goal, Q, Q_f, R, int(T), u_min, u_max, **shape)
    resolved = resolved_task_config(tc, T, x0, x_goal, Q, Q_f, R, u_min, u_max, u_ref, state_error)
    return resolved, task
