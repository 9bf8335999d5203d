"""Task resolution: a TaskConfig plus a system -> every task field filled and checked.

Sources, in order: the field itself, a keyframe of the model, the task preset, the
model (actuator ctrlrange for the control limits, qpos0 for a custom or hold task's start;
the ``hold`` preset's goal, weights and control reference: ``model_defaults.hold_task``).
Every check raises :class:`~mjx_surrogate.errors.ConfigError` naming the field.
"""

from __future__ import annotations

import mujoco
import numpy as np

from mjx_surrogate.runs.config import TaskConfig, check_finite
from mjx_surrogate.errors import ConfigError
from mjx_surrogate.runs.model_defaults import HOLD_T, control_weights, hold_controls, hold_task
from mjx_surrogate.systems import System, task_presets
from mjx_surrogate.systems.kinematics import make_points_fn, native_points_fn, point_ids
from mjx_surrogate.systems.registry import preset_fits
from mjx_surrogate.systems.system import state_labels
from mjx_surrogate.tasks import Task, make_task

MAX_T = 100_000


MODEL_PRESETS = ("custom", "hold")  # built from the model itself, for every system


def preset_fields(tc: TaskConfig, system: System) -> dict:
    if tc.preset in MODEL_PRESETS:
        return {"T": HOLD_T} if tc.preset == "hold" else {}
    presets = task_presets()
    if tc.preset not in presets:
        valid = ", ".join(list(presets) + list(MODEL_PRESETS))
        raise ConfigError("task.preset", f"unknown task {tc.preset!r}; valid: {valid}")
    preset = presets[tc.preset]
    if not preset_fits(preset, system.name):
        raise ConfigError(
            "task.preset",
            f"{tc.preset!r} is a task for {preset.system!r}, "
            f"not {system.name!r}; use a task of that system, 'hold' (keep the start) or 'custom'",
        )
    return {"state_error": "euclidean", **preset.build(system.nq, system.nv, system.nu)}


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


def _matrix(tc: TaskConfig, base: dict, name: str, n: int) -> np.ndarray:
    full, diag = getattr(tc, name), getattr(tc, name + "_diag")
    field = f"task.{name}_diag" if diag is not None else f"task.{name}"
    if full is not None and diag is not None:
        raise ConfigError(f"task.{name}_diag", f"give task.{name} or task.{name}_diag, not both")
    if diag is not None:
        check_finite(field, diag)
        if len(diag) != n:
            raise ConfigError(field, f"needs {n} entries, got {len(diag)}")
        m = np.diag(np.asarray(diag, float))
    elif full is not None:
        check_finite(field, full)
        try:
            m = np.asarray(full, float)
        except ValueError:
            raise ConfigError(field, f"must be {n}x{n}; rows of unequal length") from None
        if m.shape != (n, n):
            raise ConfigError(field, f"must be {n}x{n}, got shape {m.shape}")
    elif name in base:
        m = np.asarray(base[name], float)
    else:
        raise ConfigError(field, f"required with task.preset='custom' ({n}x{n} or {name}_diag)")
    d = np.diagonal(m)
    if np.count_nonzero(m) == np.count_nonzero(d):  # diagonal (a PDE grid's weights): its eigenvalues
        eig = np.sort(d)
    else:
        if not np.allclose(m, m.T, atol=1e-12 * max(1.0, np.abs(m).max())):
            raise ConfigError(field, "must be symmetric")
        eig = np.linalg.eigvalsh(m)
    if name == "R" and eig.min() <= 0:
        raise ConfigError(field, f"must be positive definite (smallest eigenvalue {eig.min():g})")
    if eig.min() < -1e-9 * max(1.0, eig.max()):
        raise ConfigError(field, f"must be positive semi-definite (eigenvalue {eig.min():g})")
    return m


def _state(tc: TaskConfig, name: str, labels: list[str], fallback) -> np.ndarray | None:
    v = getattr(tc, name)
    if v is None:
        return None if fallback is None else np.asarray(fallback, float)
    if len(v) != len(labels):
        raise ConfigError(f"task.{name}", f"needs {len(labels)} entries [{', '.join(labels)}], got {len(v)}")
    check_finite(f"task.{name}", v)
    return np.asarray(v, float)


def model_limits(m: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """The actuators' ctrlrange, +-inf where a control is not limited."""
    limited = m.actuator_ctrllimited.astype(bool)
    lo = np.where(limited, m.actuator_ctrlrange[:, 0], -np.inf)
    hi = np.where(limited, m.actuator_ctrlrange[:, 1], np.inf)
    return lo, hi


def _limits(tc: TaskConfig, lo_m: np.ndarray, hi_m: np.ndarray, base: dict):
    """The task's control limits: the config's, else the preset's, else the system's, which
    they may narrow but not widen."""
    nu = len(lo_m)
    out = []
    for name, model_b, sign in (("u_min", lo_m, -1.0), ("u_max", hi_m, 1.0)):
        b = getattr(tc, name)
        b = base.get(name) if b is None else b  # the config's, else the preset's, else the model's
        if b is None:
            out.append(model_b)
            continue
        if len(b) != nu:
            raise ConfigError(f"task.{name}", f"needs nu={nu} entries, got {len(b)}")
        b = np.asarray(b, float)
        if np.isnan(b).any():
            raise ConfigError(f"task.{name}", "holds NaN; use a number or +-inf")
        tol = 1e-9 * np.maximum(1.0, np.where(np.isfinite(model_b), np.abs(model_b), 0.0))
        bad = np.flatnonzero(sign * (b - model_b) > tol)
        if bad.size:
            raise ConfigError(
                f"task.{name}",
                f"wider than the model's ctrlrange in channel(s) {bad.tolist()} "
                f"({b[bad].tolist()} vs {model_b[bad].tolist()}); a task may only narrow the limits",
            )
        out.append(b)
    lo, hi = out
    if np.any(lo > hi):
        raise ConfigError("task.u_min", "must be <= task.u_max in every channel")
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
    cache = system.__dict__.setdefault("_points_fns", {})  # one function per goal set
    if ids not in cache:  # native kinematics with a native simulator: nothing to compile
        make = native_points_fn if system.backend == "native" else make_points_fn
        cache[ids] = make(system.mj_model, list(ids))
    return cache[ids]


def _tolist(v):
    if v is None:
        return None
    a = np.asarray(v, float)
    return tuple(map(tuple, a.tolist())) if a.ndim == 2 else tuple(a.tolist())


def resolve_task(tc: TaskConfig, system: System) -> tuple[TaskConfig, Task]:
    """Fill every task field (preset, keyframes, model) with shape and sign checks; returns
    the resolved TaskConfig (what config.json holds) and the Task. A function black box's
    task: :func:`mjx_surrogate.runs.function_task.resolve_function_task`."""
    if system.mj_model is None:
        from mjx_surrogate.runs.function_task import resolve_function_task

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
    x0 = _state(tc, "x0", labels, key_x0 if key_x0 is not None else base.get("x0", qpos0 if custom else None))
    u_min, u_max = _limits(tc, *model_limits(m), base)
    if tc.preset == "hold":
        base = hold_task(m, x0, u_min, u_max)
    goal_default = key_goal if key_goal is not None else base.get("x_goal", x0 if tc.goals else None)
    x_goal = _state(tc, "x_goal", labels, goal_default)
    if x_goal is None:
        raise ConfigError(
            "task.x_goal", f"required with task.preset='custom' ({nx} numbers, a goal_keyframe or task.goals)"
        )
    zeros = {"Q": np.zeros((nx, nx)), "Q_f": np.zeros((nx, nx))} if (custom and tc.goals) else {}
    Q, Q_f = _matrix(tc, {**zeros, **base}, "Q", nx), _matrix(tc, {**zeros, **base}, "Q_f", nx)
    R = _matrix(tc, {"R": control_weights(u_min, u_max), **base} if custom else base, "R", nu)
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
    hinges, quats = geodesic_indices(m) if state_error == "geodesic" else ((), ())
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
        hinges=hinges,
        quats=quats,
    )
    return resolved_task_config(tc, T, x0, x_goal, Q, Q_f, R, u_min, u_max, u_ref, state_error), task


def resolved_task_config(tc, T, x0, x_goal, Q, Q_f, R, u_min, u_max, u_ref, state_error) -> TaskConfig:
    """Every field filled: what config.json holds."""
    limited = lambda b: None if np.all(np.isinf(b)) else _tolist(b)  # noqa: E731
    return TaskConfig(
        preset=tc.preset,
        T=int(T),
        x0=_tolist(x0),
        x_goal=_tolist(x_goal),
        Q=_tolist(Q),
        Q_f=_tolist(Q_f),
        R=_tolist(R),
        u_min=limited(u_min),
        u_max=limited(u_max),
        x0_keyframe=tc.x0_keyframe,
        goal_keyframe=tc.goal_keyframe,
        u_ref=_tolist(u_ref),
        state_error=state_error,
        goals=tc.goals,
        goal_tolerance=tc.goal_tolerance,
    )
