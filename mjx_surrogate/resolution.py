"""Resolution: config -> (resolved config, system, task), every check before any compile."""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np

from mjx_surrogate.config import Config, SystemConfig, TaskConfig, check_finite, validate_static
from mjx_surrogate.errors import ConfigError
from mjx_surrogate.ilqr import ILQRParams
from mjx_surrogate.surrogates.registry import get_surrogate, library_specs
from mjx_surrogate.sysid import SysIdParams
from mjx_surrogate.systems import System, from_mjcf, make_system, task_presets
from mjx_surrogate.systems.registry import preset_fits
from mjx_surrogate.tasks import Task, make_task


class Resolved(NamedTuple):
    config: Config  # every task and system field filled in: what config.json holds
    system: System
    task: Task


def build_system_from_config(sc: SystemConfig) -> System:
    if sc.name == "mjcf":
        if not sc.mjcf_path:
            raise ConfigError("system.mjcf_path", "required when system.name is 'mjcf'")
        return from_mjcf(sc.mjcf_path, sc.backend, sc.substeps or 1, sc.timestep, sc.native_threads)
    if sc.mjcf_path:
        raise ConfigError("system.mjcf_path", f"only valid with system.name='mjcf', not {sc.name!r}")
    return make_system(sc.name, sc.backend, sc.substeps, sc.timestep, sc.native_threads)


def _preset_fields(tc: TaskConfig, system: System) -> dict:
    if tc.preset == "custom":
        return {}
    presets = task_presets()
    if tc.preset not in presets:
        valid = ", ".join(list(presets) + ["custom"])
        raise ConfigError("task.preset", f"unknown task {tc.preset!r}; valid: {valid}")
    preset = presets[tc.preset]
    if not preset_fits(preset, system.name):
        raise ConfigError(
            "task.preset",
            f"{tc.preset!r} is a task for {preset.system!r}, "
            f"not {system.name!r}; use a task of that system or 'custom'",
        )
    return preset.build(system.nq, system.nv, system.nu)


def _matrix(tc: TaskConfig, base: dict, name: str, n: int) -> np.ndarray:
    full, diag = getattr(tc, name), getattr(tc, name + "_diag")
    if full is not None and diag is not None:
        raise ConfigError(f"task.{name}_diag", f"give task.{name} or task.{name}_diag, not both")
    if diag is not None:
        check_finite(f"task.{name}_diag", diag)
        if len(diag) != n:
            raise ConfigError(f"task.{name}_diag", f"needs {n} entries, got {len(diag)}")
        m = np.diag(np.asarray(diag, float))
    elif full is not None:
        check_finite(f"task.{name}", full)
        m = np.asarray(full, float)
        if m.shape != (n, n):
            raise ConfigError(f"task.{name}", f"must be {n}x{n}, got shape {m.shape}")
    elif name in base:
        m = np.asarray(base[name], float)
    else:
        raise ConfigError(f"task.{name}", f"required with task.preset='custom' ({n}x{n})")
    if not np.allclose(m, m.T, atol=1e-12 * max(1.0, np.abs(m).max())):
        raise ConfigError(f"task.{name}", "must be symmetric")
    eig = np.linalg.eigvalsh(m)
    if name == "R" and eig.min() <= 0:
        raise ConfigError("task.R", f"must be positive definite (smallest eigenvalue {eig.min():g})")
    if eig.min() < -1e-9 * max(1.0, eig.max()):
        raise ConfigError(f"task.{name}", f"must be positive semi-definite (eigenvalue {eig.min():g})")
    return m


def _vector(tc: TaskConfig, base: dict, name: str, n: int, required: bool = True):
    v = getattr(tc, name)
    if v is None:
        if name in base:
            return np.asarray(base[name], float)
        if not required:
            return None
        raise ConfigError(f"task.{name}", f"required with task.preset='custom' ({n} numbers)")
    if len(v) != n:
        what = " ([qpos, qvel])" if name.startswith("x") else ""
        raise ConfigError(f"task.{name}", f"needs {n} entries{what}, got {len(v)}")
    if name.startswith("x"):
        check_finite(f"task.{name}", v)
    return np.asarray(v, float)


def resolve_task(tc: TaskConfig, system: System) -> TaskConfig:
    """Fill every task field from the preset and overrides, with shape and sign checks."""
    base = _preset_fields(tc, system)
    T = tc.T if tc.T is not None else base.get("T")
    if T is None:
        raise ConfigError("task.T", "required with task.preset='custom' (a positive integer)")
    if T < 1:
        raise ConfigError("task.T", f"horizon must be a positive integer, got {T}")
    nx, nu = system.nx, system.nu
    x0 = _vector(tc, base, "x0", nx)
    x_goal = _vector(tc, base, "x_goal", nx)
    Q, Q_f, R = (_matrix(tc, base, "Q", nx), _matrix(tc, base, "Q_f", nx), _matrix(tc, base, "R", nu))
    u_min = tc.u_min if tc.u_min is not None else None
    u_max = tc.u_max if tc.u_max is not None else None
    for name, b in (("u_min", u_min), ("u_max", u_max)):
        if b is not None and len(b) != nu:
            raise ConfigError(f"task.{name}", f"needs nu={nu} entries, got {len(b)}")
        if b is not None and any(np.isnan(b)):
            raise ConfigError(f"task.{name}", "holds NaN; use a number or +-inf")
    if u_min is not None and u_max is not None and np.any(np.asarray(u_min) > np.asarray(u_max)):
        raise ConfigError("task.u_min", "must be <= task.u_max in every channel")
    tolist = lambda a: tuple(map(tuple, a.tolist()))  # noqa: E731
    return TaskConfig(
        preset=tc.preset,
        T=int(T),
        x0=tuple(x0.tolist()),
        x_goal=tuple(x_goal.tolist()),
        Q=tolist(Q),
        Q_f=tolist(Q_f),
        R=tolist(R),
        u_min=u_min,
        u_max=u_max,
    )


def solver_params(cfg: Config, record_trajectories: bool = False):
    """SolverConfig -> (ILQRParams, SysIdParams)."""
    s = cfg.solver
    ilqr = ILQRParams(
        rel_tol=s.rel_tol,
        k_tol=s.k_tol,
        mu_init=s.mu_init,
        mu_min=s.mu_min,
        mu_max=s.mu_max,
        mu_factor=s.mu_factor,
        accept_ratio=s.accept_ratio,
        max_iter=s.max_iter,
        n_alphas=s.n_alphas,
        record_trajectories=record_trajectories,
    )
    sysid = SysIdParams(sigma_x=s.sigma_x, sigma_u=s.sigma_u, scheme=s.sysid, n_samples=s.n_samples)
    return ilqr, sysid


def resolve(cfg: Config) -> Resolved:
    """Validate ``cfg``, build its system and task. Raises ConfigError; compiles nothing."""
    validate_static(cfg)
    system = build_system_from_config(cfg.system)
    tc = resolve_task(cfg.task, system)
    if cfg.experiment.kind in ("d2c", "control") and cfg.solver.n_samples < system.nx + system.nu:
        raise ConfigError(
            "solver.n_samples",
            f"must be >= nx + nu = {system.nx + system.nu} "
            f"for the LTV least squares to be determined, got {cfg.solver.n_samples}",
        )
    if cfg.experiment.kind in ("predict", "analysis", "control"):
        _check_surrogates(cfg, system, int(tc.T))
    sc = dataclasses.replace(
        cfg.system,
        backend=system.backend,
        substeps=system.substeps,
        timestep=float(system.mj_model.opt.timestep),
    )
    resolved = dataclasses.replace(cfg, system=sc, task=tc)
    task = make_task(tc.x0, tc.x_goal, tc.Q, tc.Q_f, tc.R, tc.T, tc.u_min, tc.u_max)
    return Resolved(resolved, system, task)


def analysis_library_specs(cfg: Config, system: System) -> dict:
    """The libraries the analysis section names, each checked under its own field."""
    a = cfg.analysis
    out = library_specs(cfg, system, a.convergence_library, "analysis.convergence_library")
    out |= library_specs(cfg, system, a.gram_libraries, "analysis.gram_libraries")
    return out | library_specs(cfg, system, a.variance_libraries, "analysis.variance_libraries")


def _check_surrogates(cfg: Config, system: System, T: int) -> None:
    d = cfg.data
    n_test = max(1, int(round(d.test_fraction * d.n_traj)))
    n_train = d.n_traj - n_test
    if n_train < 1:
        raise ConfigError("data.test_fraction", f"leaves no training trajectory of {d.n_traj}")
    if n_train < system.nx + system.nu:
        raise ConfigError(
            "data.n_traj",
            f"the LTV fit needs >= nx + nu = {system.nx + system.nu} training trajectories, got {n_train}",
        )
    for name in cfg.surrogate.kinds:
        get_surrogate(name).validate(cfg, system, n_train * T)
    if cfg.experiment.kind == "analysis":  # the analyses fit SINDy and MLPs whatever kinds says
        analysis_library_specs(cfg, system)
        get_surrogate("mlp").validate(cfg, system, n_train * T)
