"""Static checks of a config: types, choices, signs, ranges, finiteness and the names of
registered extensions, each refused with :class:`~mjx_surrogate.errors.ConfigError` naming
the field, before any model is built (``validate_static``; the checks that need the
model are :mod:`mjx_surrogate.runs.resolution`'s)."""

from __future__ import annotations

import dataclasses
import math
import re
import typing

from mjx_surrogate.control.model_strategies import get_model_strategy
from mjx_surrogate.control.planners import PLANNERS, get_planner
from mjx_surrogate.errors import ConfigError
from mjx_surrogate.identification.sysid import SCHEMES, SysIdParams, get_scheme
from mjx_surrogate.runs.config import (
    AnalysisConfig,
    Config,
    DataConfig,
    ExperimentConfig,
    MPCConfig,
    ParallelConfig,
    SolverConfig,
    SurrogateConfig,
    SysIdConfig,
    SystemConfig,
    TaskConfig,
    check_finite,
    from_dict,
)
from mjx_surrogate.runs.experiment_kinds import get_experiment
from mjx_surrogate.runs.extension_settings import check_extensions
from mjx_surrogate.surrogates.registry import get_surrogate
from mjx_surrogate.systems.registry import USER_FUNCTION, is_function_system

_SYSID = SysIdParams()


def _check_types(cfg: Config) -> None:
    """Every field holds a value of its declared type (choices included), also when the
    config was built in Python (a notebook, a .py config) rather than parsed from a file."""
    if not isinstance(cfg, Config):
        raise ConfigError("CONFIG", f"expected a mjx_surrogate.runs.config.Config, got {type(cfg).__name__}")
    hints = typing.get_type_hints(Config)
    if not isinstance(cfg.extensions, dict):
        raise ConfigError("extensions", f"expected a mapping, got {type(cfg.extensions).__name__}")
    for f in dataclasses.fields(cfg):
        if f.name == "extensions":  # checked by extension_settings.check_extensions
            continue
        section = getattr(cfg, f.name)
        if not isinstance(section, hints[f.name]):
            raise ConfigError(f.name, f"expected a {f.name} section, got {type(section).__name__}")
    from_dict(Config, dataclasses.asdict(cfg))


_ADDRESS = re.compile(r"^[^\s:]+:\d{1,5}$|^\[[0-9A-Fa-f:.]+\]:\d{1,5}$")


def _check_parallel(pc: ParallelConfig) -> None:
    if pc.devices is not None and pc.devices < 1:
        raise ConfigError("parallel.devices", f"must be >= 1 (or unset: all devices), got {pc.devices}")
    if pc.num_processes is not None and pc.num_processes < 1:
        raise ConfigError("parallel.num_processes", f"must be >= 1 (or unset), got {pc.num_processes}")
    if pc.process_id is not None and not 0 <= pc.process_id < (pc.num_processes or 2**31):
        raise ConfigError("parallel.process_id", f"must be in [0, num_processes - 1], got {pc.process_id}")
    if pc.coordinator_address is not None and not _ADDRESS.match(pc.coordinator_address):
        raise ConfigError(
            "parallel.coordinator_address", f"must be 'host:port', got {pc.coordinator_address!r}"
        )
    given = [f for f in ("coordinator_address", "num_processes", "process_id") if getattr(pc, f) is not None]
    if given and not pc.distributed:
        raise ConfigError(f"parallel.{given[0]}", "only used with parallel.distributed: true")


def _check_mpc(m: MPCConfig) -> None:
    if not m.controllers:
        raise ConfigError("mpc.controllers", f"give one or more of {', '.join(PLANNERS)}")
    for i, c in enumerate(m.controllers):
        get_planner(c, f"mpc.controllers[{i}]")
    if len(set(m.controllers)) < len(m.controllers):
        raise ConfigError("mpc.controllers", "names a controller twice")
    for field in ("horizon", "steps", "max_iter", "n_episodes", "n_alphas"):
        v = getattr(m, field)
        if v is not None and v < 1:
            raise ConfigError(f"mpc.{field}", f"must be >= 1, got {v}")
    if m.sysid.every < 1:
        raise ConfigError("mpc.sysid.every", f"must be >= 1, got {m.sysid.every}")
    if m.samples is not None and m.samples < 2:
        raise ConfigError(
            "mpc.samples", f"must be >= 2 (the warm start and one sample), or unset, got {m.samples}"
        )
    if not m.process_noise:
        raise ConfigError("mpc.process_noise", "give one or more levels (0.0: none)")
    for i, v in enumerate(m.process_noise):
        if not (math.isfinite(v) and v >= 0):
            raise ConfigError(f"mpc.process_noise[{i}]", f"must be a finite number >= 0, got {v}")
    from mjx_surrogate.systems.plant import parse_plant, plant_label

    if not m.plants:
        raise ConfigError("mpc.plants", "give one or more plants ('model': the model itself)")
    labels = [plant_label(parse_plant(p, f"mpc.plants[{i}]")) for i, p in enumerate(m.plants)]
    if len(set(labels)) < len(labels):
        raise ConfigError("mpc.plants", f"names a plant twice: {', '.join(labels)}")
    if not (math.isfinite(m.data_level) and 0 < m.data_level <= 1):
        raise ConfigError("mpc.data_level", f"must be in (0, 1] (a fraction of U_max), got {m.data_level}")
    for field in ("sampling_sigma", "mppi_temperature"):
        v = getattr(m, field)
        if not (math.isfinite(v) and v > 0):
            raise ConfigError(f"mpc.{field}", f"must be a finite positive number, got {v}")
    if not (math.isfinite(m.refit_weight) and m.refit_weight >= 0):
        raise ConfigError(
            "mpc.refit_weight", f"must be a finite number >= 0 (0: no online refit), got {m.refit_weight}"
        )
    if m.refit_updates < 0:
        raise ConfigError(
            "mpc.refit_updates", f"must be >= 0 (0: MLPs not refitted online), got {m.refit_updates}"
        )
    if m.sampling_knots < 0:
        raise ConfigError(
            "mpc.sampling_knots", f"must be >= 0 (0: every step its own draw), got {m.sampling_knots}"
        )
    if m.sysid.n_samples is not None and m.sysid.n_samples < 1:
        raise ConfigError("mpc.sysid.n_samples", f"must be >= 1 (None: nx + nu), got {m.sysid.n_samples}")
    if m.first_plan not in ("optimum", "zeros", "reference"):
        raise ConfigError("mpc.first_plan", f"one of optimum, zeros, reference, got {m.first_plan!r}")
    if m.sysid.design not in ("gaussian", "orthogonal"):
        raise ConfigError("mpc.sysid.design", f"one of gaussian, orthogonal, got {m.sysid.design!r}")
    if not (math.isfinite(m.realtime_speed) and m.realtime_speed > 0):
        raise ConfigError(
            "mpc.realtime_speed", f"the real-time loop's clock, > 0 (1: real time), got {m.realtime_speed}"
        )
    if m.realtime and not any(get_planner(c).replans is not None for c in m.controllers):
        live = [c for c in PLANNERS if get_planner(c).replans is not None]
        raise ConfigError(
            "mpc.realtime", f"runs replanning planners in the wall-clock loop: add one of {', '.join(live)}"
        )


_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._+-]{0,99}$")


def validate_static(cfg: Config) -> None:
    """Checks that need no model: types, choices, signs, ranges, finiteness, names."""
    _check_types(cfg)
    _check_experiment(cfg.experiment)
    _check_parallel(cfg.parallel)
    _check_mpc(cfg.mpc)
    _check_solver(cfg.solver)
    _check_sysid(cfg.sysid)
    _check_system(cfg.system)
    _check_function_system(cfg.system)
    _check_task(cfg.task)
    _check_data(cfg.data)
    _check_surrogates(cfg.surrogate)
    _check_registered(cfg)
    _check_analysis(cfg.analysis)


def _at_least(lowest: int, fields: dict) -> None:
    """Each integer field >= ``lowest``."""
    for field, v in fields.items():
        if v < lowest:
            raise ConfigError(field, f"must be >= {lowest}, got {v}")


def _nonnegative(fields: dict) -> None:
    """Each field a finite number >= 0."""
    for field, v in fields.items():
        if not (math.isfinite(v) and v >= 0):
            raise ConfigError(field, f"must be a finite number >= 0, got {v}")


def _check_experiment(ex: ExperimentConfig) -> None:
    if not 0 <= ex.seed < 2**31:
        raise ConfigError("experiment.seed", f"must be an integer in [0, 2**31 - 1], got {ex.seed}")
    if ex.name is not None and (not _NAME.match(ex.name) or ".." in ex.name):
        raise ConfigError(
            "experiment.name",
            f"got {ex.name!r}; use 1-100 letters, digits, '.', '_', '+' or '-' (no '/', no '..')",
        )
    if not ex.out_dir:
        raise ConfigError("experiment.out_dir", "must name a directory")
    _at_least(1, {"experiment.n_rollouts": ex.n_rollouts, "experiment.n_noise_trials": ex.n_noise_trials})
    _nonnegative(
        {"experiment.rollout_sigma_x": ex.rollout_sigma_x, "experiment.rollout_sigma_u": ex.rollout_sigma_u}
    )
    check_finite("experiment.noise_levels", ex.noise_levels)
    if any(v < 0 for v in ex.noise_levels):
        raise ConfigError("experiment.noise_levels", "noise levels must be >= 0")


def _check_solver(s: SolverConfig) -> None:
    for field, v in (("accept_ratio", s.accept_ratio), ("alpha_factor", s.alpha_factor)):
        if not (math.isfinite(v) and 0 < v < 1):
            raise ConfigError(f"solver.{field}", f"must be in (0, 1), got {v}")
    _at_least(
        0,
        {
            "solver.reuse_max": s.reuse_max,
            "solver.stationary_restarts": s.stationary_restarts,
            "solver.sampling_search": s.sampling_search,
            "solver.receding_pass": s.receding_pass,
        },
    )
    _at_least(
        1, {"solver.max_iter": s.max_iter, "solver.n_alphas": s.n_alphas, "solver.n_starts": s.n_starts}
    )
    positive = {
        "solver.mu_max": s.mu_max,
        "solver.mu_factor": s.mu_factor - 1.0,
    }
    for field, v in positive.items():
        if not (math.isfinite(v) and v > 0):
            raise ConfigError(field, f"must be a finite positive number, got {v}")
    _nonnegative(
        {
            "solver.sysid_refine_tol": s.sysid_refine_tol,
            "solver.reuse_tol": s.reuse_tol,
            "solver.rel_tol": s.rel_tol,
            "solver.k_tol": s.k_tol,
            "solver.init_scale": s.init_scale,
            "solver.mu_init": s.mu_init,
            "solver.mu_min": s.mu_min,
            "solver.mu_raise_alpha": s.mu_raise_alpha,
        }
    )


def _check_sysid(s: SysIdConfig) -> None:
    if s.n_samples is not None and s.n_samples < 1:
        raise ConfigError("sysid.n_samples", f"must be >= 1 (or unset), got {s.n_samples}")
    if s.every < 1:
        raise ConfigError("sysid.every", f"must be >= 1, got {s.every}")
    for field in ("sigma_x", "sigma_u"):
        v = getattr(s, field)
        if v is not None and not (math.isfinite(v) and v > 0):
            raise ConfigError(f"sysid.{field}", f"must be a finite positive number (or unset), got {v}")
    _nonnegative(
        {
            "sysid.noise_floor": 0.0 if s.noise_floor is None else s.noise_floor,
            "sysid.significance": s.significance or 0.0,
            "sysid.rank_tol": s.rank_tol,
        }
    )
    if s.rank_tol >= 1:
        raise ConfigError("sysid.rank_tol", f"must be in [0, 1), got {s.rank_tol}")


def _check_system(sy: SystemConfig) -> None:
    if sy.substeps is not None and sy.substeps < 1:
        raise ConfigError("system.substeps", f"must be >= 1, got {sy.substeps}")
    for field, v in (("system.timestep", sy.timestep), ("system.control_dt", sy.control_dt)):
        if v is not None and not (math.isfinite(v) and v > 0):
            raise ConfigError(field, f"must be a finite number of seconds > 0, got {v}")
    if sy.substeps is not None and sy.control_dt is not None:
        raise ConfigError("system.control_dt", "give system.control_dt or system.substeps, not both")
    if sy.native_threads is not None and sy.native_threads < 1:
        raise ConfigError(
            "system.native_threads", f"must be >= 1 (or unset: all cores), got {sy.native_threads}"
        )


def _check_task(t: TaskConfig) -> None:
    if t.T is not None and t.T < 1:
        raise ConfigError("task.T", f"horizon must be a positive integer, got {t.T}")
    if not (math.isfinite(t.goal_tolerance) and 0 < t.goal_tolerance <= 1):
        raise ConfigError("task.goal_tolerance", f"must be in (0, 1], got {t.goal_tolerance}")
    for i, g in enumerate(t.goals):
        where = f"task.goals[{i}]"
        if not g.name:
            raise ConfigError(f"{where}.name", f"names the {g.kind} whose position is steered")
        if len(g.target) != 3:
            raise ConfigError(f"{where}.target", f"needs 3 numbers (x, y, z), got {len(g.target)}")
        check_finite(f"{where}.target", g.target)
        _nonnegative({f"{where}.weight": g.weight, f"{where}.final_weight": g.final_weight})
        if len(g.velocity) != 3:
            raise ConfigError(f"{where}.velocity", f"needs 3 numbers (m/s), got {len(g.velocity)}")
        check_finite(f"{where}.velocity", g.velocity)
        _nonnegative({f"{where}.orbit_radius": g.orbit_radius})
        if not (math.isfinite(g.orbit_period) and g.orbit_period > 0):
            raise ConfigError(f"{where}.orbit_period", f"seconds per turn, > 0, got {g.orbit_period}")
        if g.orbit_plane not in ("xy", "xz", "yz"):
            raise ConfigError(f"{where}.orbit_plane", f"one of xy, xz, yz, got {g.orbit_plane!r}")


def _check_data(d: DataConfig) -> None:
    _at_least(1, {"data.n_traj": d.n_traj, "data.n_seeds": d.n_seeds})
    check_finite("data.levels", d.levels)
    if not d.levels or any(v <= 0 for v in d.levels):
        bad = ", ".join(f"{v:g}" for v in d.levels if v <= 0) or "none"
        raise ConfigError("data.levels", f"give one or more levels > 0 (fractions of U_max), got {bad}")
    if not 0 < d.test_fraction < 1:
        raise ConfigError("data.test_fraction", f"must be in (0, 1), got {d.test_fraction}")
    if d.n_traj < 2:
        raise ConfigError("data.n_traj", f"needs >= 2 trajectories to split, got {d.n_traj}")
    _nonnegative({"data.x0_sigma": d.x0_sigma})


def _check_surrogates(sc: SurrogateConfig) -> None:
    m, mp = sc.sindy, sc.mlp
    _at_least(
        1,
        {
            "surrogate.sindy.harmonics": m.harmonics,
            "surrogate.mlp.batch_size": mp.batch_size,
            "surrogate.mlp.epochs": mp.epochs,
        },
    )
    _nonnegative(
        {
            "surrogate.sindy.stlsq_threshold": m.stlsq_threshold,
            "surrogate.sindy.stlsq_alpha": m.stlsq_alpha,
            "surrogate.mlp.weight_decay": mp.weight_decay,
        }
    )
    tol = sc.reduced_ltv_tol
    if tol is not None and not (math.isfinite(tol) and 0 <= tol < 1):
        raise ConfigError("surrogate.reduced_ltv_tol", f"must be in [0, 1) (or unset), got {tol}")
    if mp.stop_window < 0:
        raise ConfigError(
            "surrogate.mlp.stop_window", f"must be >= 0 (0: no stopping test), got {mp.stop_window}"
        )
    if not (math.isfinite(mp.stop_rel_tol) and 0 <= mp.stop_rel_tol < 1):
        raise ConfigError("surrogate.mlp.stop_rel_tol", f"must be in [0, 1), got {mp.stop_rel_tol}")
    for field, v in {"patience": mp.patience, "fixed_epochs_beside": mp.fixed_epochs_beside}.items():
        if v < 0:
            raise ConfigError(f"surrogate.mlp.{field}", f"must be >= 0 (0: off), got {v}")
    if not (math.isfinite(mp.validation_fraction) and 0 < mp.validation_fraction < 1):
        raise ConfigError(
            "surrogate.mlp.validation_fraction", f"must be in (0, 1), got {mp.validation_fraction}"
        )
    if not (math.isfinite(mp.learning_rate) and mp.learning_rate > 0):
        raise ConfigError("surrogate.mlp.learning_rate", f"must be > 0, got {mp.learning_rate}")
    if not mp.widths or any(w < 1 for w in mp.widths):
        raise ConfigError("surrogate.mlp.widths", f"needs positive layer widths, got {mp.widths}")
    bad = [e for e in mp.checkpoints if not 0 <= e <= mp.epochs]
    if bad:
        raise ConfigError("surrogate.mlp.checkpoints", f"{bad} outside 0..mlp.epochs={mp.epochs}")


def _check_analysis(a: AnalysisConfig) -> None:
    for field, v in {
        "analysis.n_datasets": a.n_datasets - 1,
        "analysis.gram_points": a.gram_points,
        "analysis.theory_max_order": a.theory_max_order,
        "analysis.theory_mc_samples": a.theory_mc_samples - 1,
        "analysis.theory_mc_trials": a.theory_mc_trials - 1,
    }.items():
        if v < 1:
            raise ConfigError(field, "too small (n_datasets, theory_mc_* >= 2; others >= 1)")
    if len(a.variance_libraries) != len(a.variance_levels):
        raise ConfigError("analysis.variance_levels", "needs one level per variance library")
    for field, vals in {
        "analysis.convergence_sindy_levels": a.convergence_sindy_levels,
        "analysis.convergence_mlp_levels": a.convergence_mlp_levels,
        "analysis.gram_mlp_levels": a.gram_mlp_levels,
        "analysis.variance_levels": a.variance_levels,
        "analysis.theory_sigmas": a.theory_sigmas,
        "analysis.gram_sindy_level": (a.gram_sindy_level,),
    }.items():
        check_finite(field, vals)
        if any(v <= 0 for v in vals):
            raise ConfigError(field, "levels and scales must be > 0")
    if a.theory_max_order > 14:
        raise ConfigError("analysis.theory_max_order", "at most 14 (exact rational arithmetic)")


def _check_registered(cfg: Config) -> None:
    """Names that select a registered extension (identification scheme, surrogate kinds,
    experiment kind) and the extensions' own settings."""
    get_experiment(cfg.experiment.kind)

    s = cfg.sysid
    scheme = get_scheme(s.scheme, "sysid.scheme")
    get_model_strategy(cfg.solver.model_strategy, "solver.model_strategy")
    mpc_name = cfg.mpc.sysid.scheme or s.scheme
    mpc_scheme = get_scheme(mpc_name, "mpc.sysid.scheme")
    for field, every, used, name in (
        ("sysid.every", s.every, scheme, s.scheme),
        ("mpc.sysid.every", cfg.mpc.sysid.every, mpc_scheme, mpc_name),
    ):
        if every > 1 and not used.one_step:
            one_step = ", ".join(n for n, s in SCHEMES.items() if s.one_step)
            raise ConfigError(
                field,
                f"> 1 needs a one-step scheme ({one_step}); {name!r} identifies from rollouts",
            )
    if (s.significance or 0.0) > 0 and not scheme.t_test:
        tested = ", ".join(n for n, sc in SCHEMES.items() if sc.t_test)
        raise ConfigError(
            "sysid.significance", f"needs a scheme with a t-test ({tested}); {s.scheme!r} has none: give 0"
        )
    if s.rank_tol != _SYSID.rank_tol and not scheme.reduced:
        reduced = ", ".join(n for n, sc in SCHEMES.items() if sc.reduced)
        raise ConfigError(
            "sysid.rank_tol", f"only a reduced scheme ({reduced}) has a basis; {s.scheme!r} has none"
        )
    if s.design != "gaussian" and not scheme.one_step:
        raise ConfigError(
            "sysid.design", f"{s.design!r} needs a one-step scheme; {s.scheme!r} draws its own perturbations"
        )
    if not cfg.surrogate.kinds:
        raise ConfigError("surrogate.kinds", "give one or more surrogate kinds")
    for i, name in enumerate(cfg.surrogate.kinds):
        get_surrogate(name, f"surrogate.kinds[{i}]")
    check_extensions(cfg)


def _check_function_system(sy: SystemConfig) -> None:
    """A function black box (system.entry, lorenz, f8) has no MuJoCo settings."""
    if (sy.name == USER_FUNCTION) != (sy.entry is not None):
        field, need = ("system.entry", "required") if sy.entry is None else ("system.entry", "only valid")
        raise ConfigError(
            field, f"{need} with system.name='{USER_FUNCTION}' (a MODULE:ATTRIBUTE or FILE.py:ATTRIBUTE)"
        )
    if sy.model_copy is not None and sy.name != "mjcf":
        raise ConfigError("system.model_copy", "only valid with system.name='mjcf'")
    if not is_function_system(sy.name):
        return
    for field in ("mjcf_path", "model_copy", "substeps", "control_dt", "timestep", "native_threads"):
        if getattr(sy, field) is not None:
            raise ConfigError(
                f"system.{field}", f"a MuJoCo setting; {sy.name!r} is a function black box, leave it unset"
            )
    if sy.backend != "auto":
        raise ConfigError("system.backend", f"{sy.name!r} is a function black box: valid: auto")
