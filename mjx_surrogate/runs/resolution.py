"""Resolution: config -> (resolved config, system, task), every check before any compile."""

from __future__ import annotations

import dataclasses
import math
import warnings
from typing import NamedTuple

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from jax.sharding import Mesh

from mjx_surrogate import sharding
from mjx_surrogate.control.ilqr import ILQRParams
from mjx_surrogate.control.model_strategies import get_model_strategy
from mjx_surrogate.control.sampling_planners import SETTINGS as SAMPLING_PLANNERS
from mjx_surrogate.cost import BLOWUP
from mjx_surrogate.errors import ConfigError, describe
from mjx_surrogate.identification.sysid import SysIdParams, get_scheme
from mjx_surrogate.runs import memory
from mjx_surrogate.runs.config import Config, SystemConfig
from mjx_surrogate.runs.experiment_kinds import (
    IDENTIFICATION,
    LTV_BASELINE,
    SURROGATES,
    get_experiment,
    needs_of,
    training_transitions,
)
from mjx_surrogate.runs.extension_settings import settings_of
from mjx_surrogate.runs.model_defaults import (
    USER_SYSTEMS,
    default_hold_limits,
    default_init,
    default_n_samples,
    default_noise_floor,
    default_perturb_x0,
    default_sigma,
    default_significance,
    default_stall_restarts,
    default_x64,
    friction_sigma,
)
from mjx_surrogate.runs.task_resolution import resolve_task
from mjx_surrogate.runs.validation import validate_static
from mjx_surrogate.surrogates.registry import get_surrogate
from mjx_surrogate.systems import FunctionSystem, from_mjcf, make_system
from mjx_surrogate.systems.black_box import BlackBox
from mjx_surrogate.systems.entry import entry_builder, entry_source, load_entry, source_digest
from mjx_surrogate.systems.function import on_mesh
from mjx_surrogate.systems.plant import check_plant
from mjx_surrogate.systems.registry import (
    USER_FUNCTION,
    default_config,
    function_builder,
    is_function_system,
    make_function_system,
)
from mjx_surrogate.systems.system import compile_mjcf
from mjx_surrogate.tasks import Task


class Resolved(NamedTuple):
    config: Config  # every task and system field filled in: what config.json holds
    system: BlackBox
    task: Task


def _substeps(sc: SystemConfig) -> int | None:
    """system.substeps, or system.control_dt divided by the physics time step."""
    if sc.control_dt is None:
        return sc.substeps
    ts = sc.timestep
    if ts is None:
        if sc.name == "mjcf":
            import os

            if not sc.mjcf_path or not os.path.isfile(sc.mjcf_path):
                raise ConfigError("system.mjcf_path", f"no such file {sc.mjcf_path!r}")
            model, _ = compile_mjcf(None, "system.mjcf_path", None, sc.mjcf_path)
        else:
            model, _ = compile_mjcf(default_config(sc.name).xml(), "system.name")
        ts = float(model.opt.timestep)
    n = round(sc.control_dt / ts)
    if n < 1 or abs(n * ts - sc.control_dt) > 1e-6 * sc.control_dt:
        raise ConfigError(
            "system.control_dt",
            f"must be a multiple of the physics time step {ts:g} s, got {sc.control_dt:g} s "
            f"(e.g. {max(n, 1) * ts:g})",
        )
    return n


def build_system_from_config(sc: SystemConfig, mesh: Mesh | None = None) -> BlackBox:
    """The system of ``sc``, its batched work spread over ``mesh``. A registered system is
    built once per process, precision and mesh (the registry's cache,
    :func:`~mjx_surrogate.systems.registry.make_system`): a System is immutable and hashes
    by identity, so experiments of one process (a reproduction, a notebook) share its
    compiled programs. A user's MJCF or function, whose files may change between calls,
    is built afresh."""
    if is_function_system(sc.name):
        return _function_system(sc, mesh)
    substeps = _substeps(sc)
    if sc.name == "mjcf":
        if not sc.mjcf_path:
            raise ConfigError("system.mjcf_path", "required when system.name is 'mjcf'")
        return from_mjcf(
            sc.mjcf_path, sc.backend, substeps or 1, sc.timestep, sc.native_threads, mesh, sc.model_copy
        )
    if sc.mjcf_path:
        raise ConfigError("system.mjcf_path", f"only valid with system.name='mjcf', not {sc.name!r}")
    return make_system(sc.name, sc.backend, substeps, sc.timestep, sc.native_threads, mesh)


def _function_system(sc: SystemConfig, mesh: Mesh | None) -> FunctionSystem:
    """A function black box: registered (built once per process and mesh) or the user's
    entry point, whose file must still be the one a replayed run recorded."""
    if sc.name != USER_FUNCTION:
        return make_function_system(sc.name, mesh)
    if sc.source_sha256 is not None:
        path = entry_source(sc.entry)
        now = source_digest(path)
        if now != sc.source_sha256:
            raise ConfigError(
                "system.source_sha256",
                f"{path!r} has changed since the run (SHA-256 {str(now)[:12]}, recorded "
                f"{sc.source_sha256[:12]}); restore the file (the run folder keeps a copy) or unset "
                "system.source_sha256 to run the new code",
            )
    return on_mesh(load_entry(sc.entry), mesh)


def check_magnitude(field: str, x, dtype, sigma_x: float) -> None:
    """Reject a state the solver cannot work from by its size alone: beyond the bound where
    a trajectory counts as diverged, or so large that the perturbations sigma_x drown in the
    round-off of ``dtype``."""
    mag = float(np.max(np.abs(np.asarray(x, float)), initial=0.0))
    if mag > BLOWUP:
        raise ConfigError(
            field,
            f"|x| up to {mag:g} is beyond {BLOWUP:g}, where the solver counts a trajectory as "
            "diverged; use coordinates of a smaller magnitude",
        )
    eps = float(np.finfo(dtype).eps)
    if mag * eps > 0.1 * sigma_x:
        fix = (
            "use smaller coordinates or a larger sysid.sigma_x"
            if eps < 1e-10
            else "use smaller coordinates, a larger sysid.sigma_x or experiment.x64"
        )
        raise ConfigError(
            field,
            f"|x| up to {mag:g} leaves a resolution of {mag * eps:.2g} in {np.dtype(dtype).name}, more "
            f"than a tenth of the identification perturbations (sysid.sigma_x {sigma_x:g}); {fix}",
        )


def check_start(system: BlackBox, task: Task, sigma_x: float) -> None:
    """Reject states the solver cannot work from: MuJoCo flags the simulation as unstable
    within one control step, or the perturbations sigma_x drown in the round-off of the
    state's magnitude at the working precision."""
    dtype = np.asarray(task.x0).dtype
    m = system.mj_model
    for field, x in (("task.x0", task.x0), ("task.x_goal", task.x_goal)):
        check_magnitude(field, x, dtype, sigma_x)
    if m is None:
        check_function_step(system, task)
        return
    d = mujoco.MjData(m)
    x = np.asarray(task.x0, float)
    d.qpos[:], d.qvel[:] = x[: m.nq], x[m.nq : m.nq + m.nv]
    if m.na:
        d.act[:] = x[m.nq + m.nv :]
    d.ctrl[:] = np.clip(np.asarray(task.u_ref, float), np.asarray(task.u_min), np.asarray(task.u_max))
    for _ in range(system.substeps):
        mujoco.mj_step(m, d)
    names = {
        mujoco.mjtWarning.mjWARN_BADQACC: "bad acceleration",
        mujoco.mjtWarning.mjWARN_BADQPOS: "bad qpos",
        mujoco.mjtWarning.mjWARN_BADQVEL: "bad qvel",
    }
    hit = [n for w, n in names.items() if d.warning[w].number > 0]
    if hit or not np.all(np.isfinite(d.qpos)):
        raise ConfigError(
            "task.x0",
            f"MuJoCo cannot simulate from this state "
            f"({', '.join(hit) or 'non-finite state'} in the first step)",
        )


def check_function_step(system: FunctionSystem, task: Task) -> None:
    """One step of a function black box from the start: an exception, a wrong shape or a
    non-finite state is bad input (one line naming the field), found before any solve."""
    field = "system.entry" if system.source is not None else "system.name"
    u = jnp.clip(task.u_ref, task.u_min, task.u_max)
    try:
        x1 = np.asarray(jax.jit(system.step)(task.x0, u))
    except Exception as exc:  # the user's code, through a callback or a trace
        raise ConfigError(field, f"the black box's step failed: {describe(exc)[:300]}") from None
    if x1.shape != (system.nx,):
        raise ConfigError(field, f"the step returned shape {x1.shape}, expected ({system.nx},)")
    if not np.all(np.isfinite(x1)):
        raise ConfigError("task.x0", "the black box's step returned a non-finite state from the start")


def solver_params(cfg: Config, record_trajectories: bool = False):
    """(ILQRParams, SysIdParams) of sections solver and sysid: every field of each is the
    section's field of the same name, but ``record_trajectories`` and the extensions' own
    settings (the model strategy's and the scheme's, where they declare any). A field the
    sysid section leaves unset (None; resolve() sets them all) keeps SysIdParams' default."""
    s = cfg.solver
    own = ("record_trajectories", "model_strategy_settings")
    strategy = get_model_strategy(s.model_strategy)
    ilqr = ILQRParams(
        record_trajectories=record_trajectories,
        model_strategy_settings=(
            settings_of(cfg, "solver", s.model_strategy) if strategy.settings is not None else None
        ),
        **{f.name: getattr(s, f.name) for f in dataclasses.fields(ILQRParams) if f.name not in own},
    )
    given = {k: v for k, v in dataclasses.asdict(cfg.sysid).items() if v is not None}
    scheme = get_scheme(cfg.sysid.scheme)
    settings = settings_of(cfg, "sysid", cfg.sysid.scheme) if scheme.settings is not None else None
    return ilqr, SysIdParams(**given, settings=settings)


def mpc_params(cfg: Config):
    """The (ILQRParams, SysIdParams) of a D2C-MPC replan: the solver's, with at most
    mpc.max_iter iterations of mpc.n_alphas step sizes and mpc's identification scheme,
    samples, design and knots; the solver's t-test where that scheme has one (``cfg``
    resolved)."""
    params, sysid = solver_params(cfg)
    m = cfg.mpc
    params = params.replace(max_iter=m.max_iter, n_alphas=m.n_alphas or params.n_alphas)
    sysid = sysid.replace(**{k: v for k, v in dataclasses.asdict(m.sysid).items() if v is not None})
    scheme = get_scheme(sysid.scheme)
    return params, sysid.replace(
        significance=sysid.significance if scheme.t_test else 0.0,
        settings=settings_of(cfg, "sysid", sysid.scheme) if scheme.settings is not None else None,
    )


def resolve(cfg: Config, local: bool = False) -> Resolved:
    """Validate ``cfg``, build its system and task. Raises ConfigError; compiles nothing.

    The system's batched work is spread over ``parallel.devices`` of the visible devices
    (of every process; ``local``: of this process only, for an experiment that one
    process of a sweep runs alone). Warns where the config runs in float64
    (``experiment.x64``, or by default: ``model_defaults.default_x64``) but JAX does not."""
    validate_static(cfg)
    if (cfg.experiment.x64 or default_x64(cfg.system.name)) and not jax.config.jax_enable_x64:
        warnings.warn(
            f"experiment.x64: {cfg.system.name!r} runs in float64, but jax_enable_x64 is off, so this "
            "run is float32, whose round-off swamps small perturbations: call "
            "mjx_surrogate.configure_runtime(x64=True) before resolve",
            stacklevel=2,
        )
    sigma = default_sigma(cfg.system.name not in USER_SYSTEMS)
    sigma_x = sigma if cfg.sysid.sigma_x is None else cfg.sysid.sigma_x
    for field in ("x0", "x_goal"):  # as given, before anything is built or compiled
        if getattr(cfg.task, field) is not None:
            check_magnitude(f"task.{field}", getattr(cfg.task, field), jnp.result_type(float), sigma_x)
    pool = jax.local_devices() if local else jax.devices()
    mesh = sharding.device_mesh(cfg.parallel.devices, pool)
    system = build_system_from_config(cfg.system, mesh)
    tc, task = resolve_task(cfg.task, system)
    needs, kind = needs_of(cfg), get_experiment(cfg.experiment.kind)
    oracle = cfg.experiment.exact_oracle
    if oracle is None:  # on for the registered systems whose full-order solve fits here
        oracle = cfg.system.name != "mjcf" and memory.oracle_fits(task, system.nx, system.nu)
    reduced = get_scheme(cfg.sysid.scheme).reduced
    n = cfg.sysid.n_samples or default_n_samples(system.nx, system.nu, reduced)
    memory.check_solve_memory(cfg, system, task, n, oracle)  # the dense arrays first: the grid
    n_samples = _check_samples(cfg, system, int(tc.T), IDENTIFICATION in needs)
    unset = cfg.sysid.sigma_x is None or cfg.sysid.sigma_u is None
    if cfg.system.name == "mjcf" and unset:  # a user's model: above its dry friction's break-away
        sigma = friction_sigma(sigma, system.mj_model, np.asarray(task.x0, float), task.u_min, task.u_max)
        sigma_x = sigma if cfg.sysid.sigma_x is None else cfg.sysid.sigma_x
    sigma_u = sigma if cfg.sysid.sigma_u is None else cfg.sysid.sigma_u
    check_start(system, task, sigma_x)
    if SURROGATES in needs:
        _check_surrogates(dataclasses.replace(cfg, task=tc), system, LTV_BASELINE in needs)
    kind.validate(dataclasses.replace(cfg, task=tc), system)
    mpc = _resolve_mpc(cfg, system, int(tc.T), n_samples)
    if system.mj_model is None:
        sc = dataclasses.replace(cfg.system, source_sha256=source_digest(system.source))
    else:
        sc = dataclasses.replace(
            cfg.system,
            backend=system.backend,
            substeps=system.substeps,
            control_dt=None,
            timestep=float(system.mj_model.opt.timestep),
        )
    ex = dataclasses.replace(
        cfg.experiment,
        exact_oracle=oracle,
        # a function without derivatives (a host function) is judged against central differences
        oracle="finite_difference"
        if system.mj_model is None and system.exact_step is None
        else cfg.experiment.oracle,
    )
    init = cfg.solver.init or default_init(cfg.system.name)
    if init == "hold" and system.mj_model is None:
        raise ConfigError(
            "solver.init", "'hold' needs a MuJoCo model's actuators; valid: zeros, random, u_ref"
        )
    s = cfg.sysid
    floor = default_noise_floor(cfg.system.name) if s.noise_floor is None else s.noise_floor
    perturb_x0 = default_perturb_x0(cfg.system.name) if s.perturb_x0 is None else s.perturb_x0
    hold_limits = default_hold_limits(cfg.system.name) if s.hold_limits is None else s.hold_limits
    significance = s.significance
    if significance is None:  # the t-test where the model has loose objects and the scheme has it
        tested = get_scheme(s.scheme).t_test
        significance = default_significance(cfg.system.name, system.mj_model) if tested else 0.0
    sysid = dataclasses.replace(
        s,
        n_samples=n_samples,
        sigma_x=sigma_x,
        sigma_u=sigma_u,
        noise_floor=floor,
        perturb_x0=perturb_x0,
        hold_limits=hold_limits,
        significance=significance,
    )
    stall = cfg.solver.stall_restarts
    stall = default_stall_restarts(cfg.system.name) if stall is None else stall
    solver = dataclasses.replace(cfg.solver, init=init, stall_restarts=stall)
    resolved = dataclasses.replace(
        cfg, system=sc, task=tc, experiment=ex, solver=solver, sysid=sysid, mpc=mpc
    )
    return Resolved(resolved, system, task)


def _check_samples(cfg: Config, system: BlackBox, T: int, identifies: bool) -> int:
    """The identification's samples (the config's or the default), checked against what its
    scheme needs where the experiment identifies."""
    reduced = get_scheme(cfg.sysid.scheme).reduced
    n_samples = cfg.sysid.n_samples or default_n_samples(system.nx, system.nu, reduced)
    if identifies:
        if reduced and not 1 <= n_samples <= system.nx:
            raise ConfigError(
                "sysid.n_samples",
                f"the reduced scheme's snapshots (its largest rank) must be between 1 and nx = {system.nx}, "
                f"got {n_samples}",
            )
        if not reduced and n_samples < system.nx + system.nu:
            raise ConfigError(
                "sysid.n_samples",
                f"must be >= nx + nu = {system.nx + system.nu} "
                f"for the LTV least squares to be determined, got {n_samples}",
            )
        memory.check_identification_batch(cfg, system.nx, system.nu, T, n_samples)
    return n_samples


def _resolve_mpc(cfg: Config, system: BlackBox, T: int, solver_samples: int):
    """Section mpc with its defaults filled (horizon and steps: the task's T; D2C-MPC's
    samples: nx + nu with a one-step scheme, else the solver's), checked against the
    system and the task."""
    m, m_min, ms = cfg.mpc, system.nx + system.nu, cfg.mpc.sysid
    name = ms.scheme or cfg.sysid.scheme
    scheme = get_scheme(name, "mpc.sysid.scheme")
    if scheme.one_step:
        n, design = ms.n_samples or m_min, ms.design
    else:  # perturbed rollouts or a reduced basis: the sysid section's design
        n, design = ms.n_samples or solver_samples, cfg.sysid.design
    if scheme.reduced and not 1 <= n <= system.nx:
        raise ConfigError(
            "mpc.sysid.n_samples", f"the reduced scheme's rank: between 1 and nx = {system.nx}, got {n}"
        )
    if not scheme.reduced and n < m_min:
        raise ConfigError(
            "mpc.sysid.n_samples",
            f"must be >= nx + nu = {m_min} for the LTV least squares to be determined, got {n}",
        )
    ms = dataclasses.replace(ms, scheme=name, n_samples=n, design=design)
    m = dataclasses.replace(m, horizon=m.horizon or T, steps=m.steps or T, sysid=ms)
    if m.sampling_knots > m.horizon:
        raise ConfigError(
            "mpc.sampling_knots",
            f"at most the horizon, {m.horizon} steps (0: every step), got {m.sampling_knots}",
        )
    for name in m.controllers:  # a sampling planner's own knots and elites
        own = settings_of(cfg, "mpc", name) if name in SAMPLING_PLANNERS else None
        if own is not None and own.knots is not None and own.knots > m.horizon:
            raise ConfigError(
                f"mpc.{name}.knots",
                f"at most the horizon, {m.horizon} steps (0: every step), got {own.knots}",
            )
        if own is not None and getattr(own, "elites", 1) > (own.samples or m.samples or 2**31):
            raise ConfigError(f"mpc.{name}.elites", f"at most the samples, got {own.elites}")
    if m.replan_hz is not None:
        every = replan_every(m, float(system.dt))
        if every < 1 or m.steps % every:
            raise ConfigError(
                "mpc.replan_hz",
                f"a rate whose period is a whole number of control steps of {float(system.dt):g} s "
                f"dividing mpc.steps = {m.steps} (e.g. {1 / float(system.dt):g}, "
                f"{1 / (2 * float(system.dt)):g}), got {m.replan_hz}",
            )
    if m.horizon_end == "task" and m.steps > T:
        raise ConfigError(
            "mpc.horizon_end",
            f"'task' ends every plan at the task's end, task.T = {T}: needs mpc.steps <= {T}, "
            f"got {m.steps} ('receding' for longer episodes)",
        )
    if m.horizon_end == "auto":
        m = dataclasses.replace(m, horizon_end="task" if m.steps <= T else "receding")
    if "tvlqr" in m.controllers and m.steps > T:
        raise ConfigError(
            "mpc.steps",
            f"'tvlqr' tracks the offline optimum of task.T = {T} steps: at most {T}, got {m.steps}",
        )
    build = plant_builder(cfg, system)
    for i, text in enumerate(m.plants):
        try:
            check_plant(system, text, build)
        except ConfigError as e:
            raise ConfigError(f"mpc.plants[{i}]", str(e).removeprefix(f"{e.field}: ")) from None
    return m


def replan_every(m, dt: float) -> int:
    """Control steps from one replan to the next: 1 / (mpc.replan_hz dt), or 1 when unset;
    0 where that is not a whole number (to 1e-9)."""
    if m.replan_hz is None:
        return 1
    if not (math.isfinite(m.replan_hz) and m.replan_hz > 0):
        return 0
    r = 1.0 / (m.replan_hz * dt)
    return int(round(r)) if abs(r - round(r)) <= 1e-9 * max(1.0, r) else 0


def plant_builder(cfg: Config, system: BlackBox):
    """The function that builds the function black box ``system`` (its MPC plants are calls
    of it with other keyword arguments); None for a MuJoCo model."""
    if system.mj_model is not None:
        return None
    if cfg.system.name == USER_FUNCTION:
        return entry_builder(cfg.system.entry)
    return function_builder(cfg.system.name)


def _check_surrogates(cfg: Config, system: BlackBox, ltv_baseline: bool) -> None:
    """Section surrogate and the data split (``cfg.task`` resolved); with
    ``ltv_baseline``, enough trajectories for the per-step LTV fit too."""
    d = cfg.data
    n_test = max(1, int(round(d.test_fraction * d.n_traj)))
    n_train = d.n_traj - n_test
    if n_train < 1:
        raise ConfigError("data.test_fraction", f"leaves no training trajectory of {d.n_traj}")
    if ltv_baseline and n_train < system.nx + system.nu:
        raise ConfigError(
            "data.n_traj",
            f"the LTV fit needs >= nx + nu = {system.nx + system.nu} training trajectories, got {n_train}",
        )
    for name in cfg.surrogate.kinds:
        get_surrogate(name).validate(cfg, system, training_transitions(cfg))
