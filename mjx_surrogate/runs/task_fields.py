"""The task fields both task resolutions share (a MuJoCo model's,
:mod:`~mjx_surrogate.runs.task_resolution`, and a function black box's,
:mod:`~mjx_surrogate.runs.function_task`): the preset's fields, weight matrices, states and
control limits, each checked and refused naming its field, and the resolved TaskConfig."""

from __future__ import annotations

import numpy as np

from mjx_surrogate.errors import ConfigError
from mjx_surrogate.runs.config import TaskConfig, check_finite
from mjx_surrogate.runs.model_defaults import HOLD_T
from mjx_surrogate.systems import task_presets
from mjx_surrogate.systems.registry import preset_fits

MAX_T = 100_000


MODEL_PRESETS = ("custom", "hold")  # built from the model itself, for every system


def preset_fields(tc: TaskConfig, system) -> dict:
    """The preset's fields for ``system`` (none for a model preset, T for ``hold``)."""
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


def matrix_field(tc: TaskConfig, base: dict, name: str, n: int) -> np.ndarray:
    """Weight ``name`` (Q, Q_f, R): the full one [n, n], its diagonal, or the preset's;
    symmetric and positive semi-definite (R positive definite). A state weight given as its
    diagonal (``{name}_diag``, or a preset's vector) stays its diagonal [n], so that a grid
    of many cells has no n x n array (:func:`mjx_surrogate.tasks.quadratic`); R is always
    the matrix."""
    full, diag = getattr(tc, name), getattr(tc, name + "_diag")
    field = f"task.{name}_diag" if diag is not None else f"task.{name}"
    if full is not None and diag is not None:
        raise ConfigError(f"task.{name}_diag", f"give task.{name} or task.{name}_diag, not both")
    if diag is not None:
        check_finite(field, diag)
        if len(diag) != n:
            raise ConfigError(field, f"needs {n} entries, got {len(diag)}")
        m = np.asarray(diag, float)
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
    if m.ndim == 1:  # a diagonal: its entries are its eigenvalues
        eig = np.sort(m)
    elif np.count_nonzero(m) == np.count_nonzero(d := np.diagonal(m)):  # a diagonal matrix
        eig = np.sort(d)
    else:
        if not np.allclose(m, m.T, atol=1e-12 * max(1.0, np.abs(m).max())):
            raise ConfigError(field, "must be symmetric")
        eig = np.linalg.eigvalsh(m)
    if name == "R" and eig.min() <= 0:
        raise ConfigError(field, f"must be positive definite (smallest eigenvalue {eig.min():g})")
    if eig.min() < -1e-9 * max(1.0, eig.max()):
        raise ConfigError(field, f"must be positive semi-definite (eigenvalue {eig.min():g})")
    return np.diag(m) if name == "R" and m.ndim == 1 else m


def state_field(tc: TaskConfig, name: str, labels: list[str], fallback) -> np.ndarray | None:
    """State ``name`` [nx] (x0, x_goal), finite and one entry per label, else ``fallback``."""
    v = getattr(tc, name)
    if v is None:
        return None if fallback is None else np.asarray(fallback, float)
    if len(v) != len(labels):
        raise ConfigError(f"task.{name}", f"needs {len(labels)} entries [{', '.join(labels)}], got {len(v)}")
    check_finite(f"task.{name}", v)
    return np.asarray(v, float)


def limits_field(tc: TaskConfig, lo_m: np.ndarray, hi_m: np.ndarray, base: dict):
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


def _tolist(v):
    if v is None:
        return None
    a = np.asarray(v, float)
    return tuple(map(tuple, a.tolist())) if a.ndim == 2 else tuple(a.tolist())


def resolved_task_config(tc, T, x0, x_goal, Q, Q_f, R, u_min, u_max, u_ref, state_error) -> TaskConfig:
    """Every field filled: what config.json holds."""
    limited = lambda b: None if np.all(np.isinf(b)) else _tolist(b)  # noqa: E731
    full = lambda W: None if np.ndim(W) == 1 else _tolist(W)  # noqa: E731
    diag = lambda W: _tolist(W) if np.ndim(W) == 1 else None  # noqa: E731
    return TaskConfig(
        preset=tc.preset,
        T=int(T),
        x0=_tolist(x0),
        x_goal=_tolist(x_goal),
        Q=full(Q),
        Q_f=full(Q_f),
        Q_diag=diag(Q),
        Q_f_diag=diag(Q_f),
        R=_tolist(R),
        u_min=limited(u_min),
        u_max=limited(u_max),
        x0_keyframe=tc.x0_keyframe,
        goal_keyframe=tc.goal_keyframe,
        u_ref=_tolist(u_ref),
        state_error=state_error,
        goals=tc.goals,
        goal_tolerance=tc.goal_tolerance,
        hessian=tc.hessian,
    )
