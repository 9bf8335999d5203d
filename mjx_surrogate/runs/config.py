"""Frozen dataclass configs: system, task, solver and experiment sections.

A config is plain data. ``resolve`` (in :mod:`mjx_surrogate.runs.resolution`) turns it into a
system, a task and a fully resolved config; every check there raises
:class:`~mjx_surrogate.errors.ConfigError` naming the field, before any XLA compile.
"""

from __future__ import annotations

import dataclasses
import math
import re
import types
import typing
from typing import Annotated, Any, Dict, Literal, Optional, Tuple

import tyro

from mjx_surrogate.errors import ConfigError
from mjx_surrogate.control.ilqr import ILQRParams
from mjx_surrogate.identification.sysid import SysIdParams

_ILQR, _SYSID = ILQRParams(), SysIdParams()

Vector = Optional[Tuple[float, ...]]
Matrix = Optional[Tuple[Tuple[float, ...], ...]]


@dataclasses.dataclass(frozen=True)
class SystemConfig:
    """Which black box to simulate and how.

    name: a registered system (pendulum, cartpole, fish, swimmerN; the function black
      boxes lorenz, f8, and the PDEs burgersN, allen_cahnN, allen_cahn2dN on N cells per
      side), "mjcf" (the user's MJCF file) or "python" (the user's function).
    mjcf_path: the user's MJCF file, with name="mjcf".
    model_copy: a compiled copy of that model (a run folder's model.mjb), simulated instead
      of the file at mjcf_path, which may have changed since; a replay sets it.
    entry: with name="python", the user's black box as MODULE:ATTRIBUTE or
      FILE.py:ATTRIBUTE, a FunctionSystem or a function returning one (from_numpy,
      from_jax; docs/function_systems.md).
    source_sha256: the SHA-256 of the entry's file, recorded by a run; a replay refuses
      to run when the file has changed.
    backend: "mjx", "native", or "auto" (the measured faster one on the CPU); a function
      black box runs as it is given ("auto").
    substeps: physics steps per control step (None: the system's default, 1 for "mjcf").
    control_dt: the control time step in seconds instead of substeps (a multiple of the
      physics time step).
    timestep: physics time step override in seconds (None: the model's).
    native_threads: threads of the native backend (None: all cores).
    """

    name: str = "pendulum"
    mjcf_path: Optional[str] = None
    model_copy: Optional[str] = None
    entry: Optional[str] = None
    source_sha256: Optional[str] = None
    backend: Literal["auto", "mjx", "native"] = "auto"
    substeps: Optional[int] = None
    control_dt: Optional[float] = None
    timestep: Optional[float] = None
    native_threads: Optional[int] = None


@dataclasses.dataclass(frozen=True)
class PointGoal:
    """A goal on the world position of a named site or body (``kind``), in metres.

    Adds 1/2 weight |p_t - target|^2 to every running cost and 1/2 final_weight
    |p_T - target|^2 to the terminal cost; p comes from the model's kinematics, the
    dynamics stay a black box.
    """

    name: str = ""
    target: Tuple[float, ...] = (0.0, 0.0, 0.0)
    weight: float = 0.0
    final_weight: float = 1.0
    kind: Literal["site", "body"] = "site"


@dataclasses.dataclass(frozen=True)
class TaskConfig:
    """Start, goal, horizon and quadratic weights (cost convention in docs/results.md).

    preset: a task preset (see ``mjx_surrogate.systems.task_presets()``) filling every
    field left as None; "hold" (any model: keep the start, qpos0 or x0_keyframe, for 50
    control steps; ``model_defaults.hold_task``); or "custom" (then x_goal, T and weights
    are required).
    Q, Q_f, R: full matrices; Q_diag, Q_f_diag, R_diag: diagonal shortcuts.
    u_min, u_max: box limits on the controls, enforced by the solver; by default the
      preset's, else the model's actuator ctrlrange, which they may narrow but not widen.
    x0_keyframe, goal_keyframe: a keyframe of the model (name or index) giving x0, or
      x_goal and the control reference u_ref (its ctrl).
    u_ref: the control the R term pulls towards (default zeros).
    state_error: "euclidean" (x - x_goal) or "geodesic" (hinge angles wrapped to
      (-pi, pi], quaternions by their rotation vector); None: the preset's, else geodesic.
    goals: PointGoal terms on sites or bodies, added to the quadratic cost.
    goal_tolerance: the goal counts as reached when the terminal cost is at most this
      fraction of the terminal cost at x0 (docs/results.md).
    """

    preset: str = "pendulum_d2c"
    T: Optional[int] = None
    x0: Vector = None
    x_goal: Vector = None
    Q: Matrix = None
    Q_f: Matrix = None
    R: Matrix = None
    Q_diag: Vector = None
    Q_f_diag: Vector = None
    R_diag: Vector = None
    u_min: Vector = None
    u_max: Vector = None
    x0_keyframe: Optional[str] = None
    goal_keyframe: Optional[str] = None
    u_ref: Vector = None
    state_error: Optional[Literal["euclidean", "geodesic"]] = None
    goals: Tuple[PointGoal, ...] = ()
    goal_tolerance: float = 0.01


@dataclasses.dataclass(frozen=True)
class SolverConfig:
    """iLQR and data-driven (D2C) iLQR settings.

    sysid: a registered identification scheme: "central_difference" (D2C 2.0 one-step
    scheme), "forward_difference" (one-sided, half the simulator calls, first-order
    accurate), "rollout" (the paper's open-loop perturbed rollouts), "closed_loop"
    (perturbed rollouts under the current feedback gains), "reduced" (RO-D2C for
    black boxes with many states, e.g. PDEs: a snapshot basis of n_samples rollouts and
    central differences in it, ``mjx_surrogate.identification.sysid_reduced``), or one registered with
    ``mjx_surrogate.identification.sysid.register_scheme``.
    sysid_rank_tol: with sysid="reduced", the fraction of the snapshots' energy the basis
    may leave out (its rank is at most n_samples).
    sysid_every: with a one-step scheme, identify only every k-th time step (and the
    last) and interpolate linearly between (``mjx_surrogate.identification.sysid_knots``).
    sysid_design: a one-step scheme's perturbations: "gaussian" (D2C 2.0: i.i.d.
    N(0, sigma^2)) or "orthogonal" (blocks of nx + nu orthogonal rows: with n_samples =
    nx + nu the fewest samples, perfectly conditioned).
    sysid_refine_tol: with sysid_every > 1, identify at every step from the first accepted
    step that gains at most this fraction of the cost, or where the solver would have
    stopped (0: only there); minima are declared on every-step models only.
    mu_raise_alpha: a step accepted only at a size below this raises mu (up to mu_max)
    instead of lowering it: a trust region on the step (``mjx_surrogate.control.ilqr``); 0: off.
    reuse_tol, reuse_max: after an accepted step whose actual decrease was within reuse_tol
    of the model's promise, carry the model over (secant update) instead of identifying,
    at most reuse_max iterations in a row (``mjx_surrogate.control.local_model``); 0: always identify.
    """

    # (defaults: the solver's own ILQRParams, one source of truth)
    max_iter: int = _ILQR.max_iter  # iLQR iterations at most
    rel_tol: float = _ILQR.rel_tol  # stop when the relative cost decrease is at most this
    k_tol: float = _ILQR.k_tol  # stop when max |k| <= k_tol (1 + max |U|)
    mu_init: float = _ILQR.mu_init  # the Levenberg-Marquardt regularisation at the start
    mu_min: float = _ILQR.mu_min  # mu is kept at least this
    mu_max: float = _ILQR.mu_max  # stop (stalled) when a step needs more regularisation than this
    mu_factor: float = _ILQR.mu_factor  # mu shrinks / grows by this factor
    n_alphas: int = _ILQR.n_alphas  # line-search step sizes, tried in one batch
    accept_ratio: float = _ILQR.accept_ratio  # accept a step when actual / promised decrease > this
    alpha_factor: float = _ILQR.alpha_factor  # step sizes alpha_factor ** (0 .. n_alphas - 1)
    mu_raise_alpha: float = _ILQR.mu_raise_alpha  # accepted step sizes below this raise mu
    sysid: str = "central_difference"  # a registered scheme (mjx_surrogate.identification.sysid.SCHEMES)
    sysid_every: int = 1  # one-step schemes: identify every k-th step, interpolate between
    sysid_design: Literal["gaussian", "orthogonal"] = "gaussian"  # one-step perturbations
    sysid_refine_tol: float = _ILQR.refine_tol  # sysid_every > 1: every step once a step gains <= this
    reuse_tol: float = _ILQR.reuse_tol  # carry the model over when |ratio - 1| <= this
    reuse_max: int = _ILQR.reuse_max  # ... at most this many iterations in a row
    n_samples: Optional[int] = None  # None: max(20, 2 (nx + nu)); reduced: min(nx, max(16, 4 nu))
    sigma_x: Optional[float] = None  # None: model_defaults.default_sigma
    sigma_u: Optional[float] = None
    sysid_noise_floor: Optional[float] = None  # zero entries below c eps |x| / sigma (None: model_defaults)
    sysid_perturb_x0: Optional[bool] = None  # one-step schemes perturb the given start (None: model_defaults)
    sysid_hold_limits: Optional[bool] = None  # one-step schemes hold joints at a limit (None: model_defaults)
    sysid_significance: float = 0.0  # zero identified coefficients with |t| <= this (0: off)
    sysid_rank_tol: float = _SYSID.rank_tol  # reduced scheme: energy the snapshot basis leaves out
    init: Optional[Literal["zeros", "random", "u_ref", "hold"]] = None  # None: model_defaults.default_init
    init_scale: float = 0.1
    n_starts: int = 1
    # a single start that ends stationary is solved again from this many starts spread over
    # the actuators' range (mjx_surrogate.runs.restart); 0: off
    stationary_restarts: int = 8


@dataclasses.dataclass(frozen=True)
class DataConfig:
    """Data sets sampled around the task's optimum (mjx_surrogate.identification.data).

    levels: control perturbation std as fractions of U_max (largest |u*| per channel).
    n_traj trajectories of the task's horizon per level; split train : test by
    test_fraction (paper: 2000 trajectories, 9 : 1). n_seeds data sets per level.
    """

    n_traj: int = 2000
    levels: Tuple[float, ...] = (0.05, 0.10, 0.15, 0.25, 0.30, 0.60, 1.00)
    x0_sigma: float = 0.0
    test_fraction: float = 0.1
    n_seeds: int = 1


@dataclasses.dataclass(frozen=True)
class SindyConfig:
    """SINDy-style least squares (surrogate kind "sindy").

    libraries: names "poly<d>" with optional suffixes "_nocross", "_trig", "_prod"
    (aliases: cubic_trig = poly3_trig, quartic = poly4, quartic_trig = poly4_trig).
    trig_coords: indices into z = [x, u] for sin/cos terms (None: the hinge angles).
    stlsq_threshold > 0 fits by STLSQ (columns normalised), else plain least squares.
    """

    libraries: Tuple[str, ...] = ("cubic_trig", "quartic", "quartic_trig")
    trig_coords: Optional[Tuple[int, ...]] = None
    harmonics: int = 1
    stlsq_threshold: float = 0.0
    stlsq_alpha: float = 0.05
    method: Literal["svd", "normal"] = "svd"


@dataclasses.dataclass(frozen=True)
class MLPConfig:
    """Flax MLPs (surrogate kind "mlp"); the paper's by default: 32 -> ReLU -> 64 -> ReLU,
    Adam 1e-4, weight decay 1e-6, minibatches of 256. checkpoints: epochs whose
    parameters are kept (analysis). epochs: the most epochs; with stop_window > 0 training
    stops earlier once the best test loss fell by less than stop_rel_tol (relative) over the
    last stop_window epochs (the convergence test)."""

    widths: Tuple[int, ...] = (32, 64)
    learning_rate: float = 1e-4
    weight_decay: float = 1e-6
    batch_size: int = 256
    epochs: int = 200
    checkpoints: Tuple[int, ...] = ()
    stop_window: int = 0
    stop_rel_tol: float = 0.0


@dataclasses.dataclass(frozen=True)
class PodSindyConfig:
    """SINDy on POD coefficients (surrogate kind "pod_sindy", for black boxes with many
    states such as PDEs): the leading ``rank`` POD modes of the training states, one model
    per library name (as surrogate.sindy.libraries; no trig terms) on [modes, u]."""

    rank: int = 8
    libraries: Tuple[str, ...] = ("poly1", "poly2")


@dataclasses.dataclass(frozen=True)
class SurrogateConfig:
    """Global surrogates fitted on the data sets (``mjx_surrogate.surrogates``).

    kinds: registered surrogate kinds to fit, in order (built in: "sindy", "mlp",
      "pod_sindy").
    increment: models predict x_{t+1} - x_t instead of x_{t+1}.
    reduced_ltv_tol: the prediction study also fits the local LTV model in the data's own
      snapshot basis per t (energy rule as solver.sysid_rank_tol), "LTV reduced": for black
      boxes with many states, whose data around the optimum span few directions per t
      (docs/pde.md); None: not fitted.
    One nested section per built-in kind.
    """

    kinds: Tuple[str, ...] = ("sindy", "mlp")
    increment: bool = False
    reduced_ltv_tol: Optional[float] = None
    sindy: SindyConfig = SindyConfig()
    mlp: MLPConfig = MLPConfig()
    pod_sindy: PodSindyConfig = PodSindyConfig()


@dataclasses.dataclass(frozen=True)
class AnalysisConfig:
    """The paper's analyses (kinds "analysis" and "theory").

    n_datasets: data sets drawn with different seeds from one sampling distribution.
    convergence_sindy_levels / convergence_mlp_levels: levels of the model-convergence
    figures (paper: SINDy 10 % and 100 %, MLP 5 % and 25 %), with convergence_library.
    gram_sindy_level, gram_libraries: the Gram-matrix spectra (paper: 5 %, cubic + trig
    and quartic). gram_mlp_levels: the MLP parameter-Jacobian Gram (paper: 5 %, 15 %) on
    gram_points transitions. variance_libraries / variance_levels (paired): projections
    of the error on the basis across data sets (paper: cubic at 5 %, quartic + trig at 15 %).
    theory_*: orders 1..theory_max_order, Gaussian scales, Monte Carlo size.
    """

    n_datasets: int = 5
    convergence_library: str = "cubic_trig"
    convergence_sindy_levels: Tuple[float, ...] = (0.10, 1.00)
    convergence_mlp_levels: Tuple[float, ...] = (0.05, 0.25)
    gram_sindy_level: float = 0.05
    gram_libraries: Tuple[str, ...] = ("cubic_trig", "quartic")
    gram_mlp_levels: Tuple[float, ...] = (0.05, 0.15)
    gram_points: int = 1000
    variance_libraries: Tuple[str, ...] = ("cubic", "quartic_trig")
    variance_levels: Tuple[float, ...] = (0.05, 0.15)
    theory_max_order: int = 10
    theory_sigmas: Tuple[float, ...] = (0.5, 1.0)
    theory_mc_samples: int = 1000
    theory_mc_trials: int = 400


MPC_CONTROLLERS = ("d2c", "oracle", "tvlqr", "surrogates", "predictive_sampling", "mppi")


@dataclasses.dataclass(frozen=True)
class MPCConfig:
    """Receding-horizon control on the black box (kind "mpc", docs/mpc.md).

    controllers: from "d2c" (LTV models identified at every replan), "oracle" (exact
      Jacobians: experiment.oracle; only where experiment.exact_oracle is on), "tvlqr"
      (tracking the offline D2C optimum, no replanning), "surrogates" (iLQR on every
      model of surrogate.kinds, fitted on data.n_traj trajectories around the optimum at
      data_level), "predictive_sampling" and "mppi" (derivative-free, on the black box).
    horizon: control steps per plan H (None: task.T). steps: control steps of an episode
      (None: task.T; at most task.T with "tvlqr"). max_iter: iLQR iterations per replan.
    process_noise: standard deviations (state units) of the noise added after every plant
      step, one set of episodes per level. plants: the black boxes the episodes run on,
      each "model" (the controller's own) or changes NAME=VALUE[,NAME=VALUE...]: on a
      MuJoCo model scale factors of mass (masses and inertias), length (body geometry,
      masses kept), damping (joint damping) or gravity, e.g. "mass=1.5,damping=2"; on a
      function black box keyword arguments of the function that builds it, e.g. "rho=30"
      for Lorenz (docs/mpc.md).
    n_episodes: episodes per controller and condition (their own keys).
    samples: samples per replan of the sampling MPCs (None: matched to D2C-MPC's median
      black-box steps per control step, else 64). sampling_sigma: their spread, control
      units. mppi_temperature: MPPI's temperature as a fraction of the first plan's cost.
      sampling_knots: 0 draws their perturbations independently at every control step;
      k >= 1 draws them at k knots spread over the horizon and interpolates linearly
      between (smooth plans, as hydrax's spline planners; at most the horizon).
    refit_weight: > 0 adds, for every SINDy model, SINDy-MPC refitted online before every
      replan on its training transitions and the episode's own, each of these weighing
      refit_weight training ones (``mpc_online``; SINDy-MPC's low-data setting); 0: off.
      refit_updates: with refit_weight > 0, MLP-MPC refitted online too: the network takes
      this many steps of its own optimiser (surrogate.mlp) on that weighted loss before
      every replan; 0: MLPs are not refitted.
    first_plan: every planner's first warm start: "optimum" (the offline D2C optimum's
      first H controls) or "zeros".
    n_samples, sysid_design: D2C-MPC's identification at every replan (the solver's scheme
      and perturbation sizes otherwise): samples per identification (None: nx + nu with a
      one-step scheme, the fewest that determine [A_t B_t]; else solver.n_samples) in
      design sysid_design ("orthogonal": with nx + nu samples the Gram matrix is exactly
      diagonal, paper Section 3; "gaussian": D2C 2.0's). The offline optimum keeps the
      solver's settings.
    """

    controllers: Tuple[str, ...] = (
        MPC_CONTROLLERS  # d2c, oracle, tvlqr, surrogates, predictive_sampling, mppi
    )
    horizon: Optional[int] = None  # control steps per plan H (None: task.T)
    steps: Optional[int] = None  # control steps of an episode (None: task.T)
    max_iter: int = 5  # iLQR iterations per replan
    process_noise: Tuple[float, ...] = (0.0, 0.01)  # noise std added after each plant step, per level
    plants: Tuple[str, ...] = ("model",)  # "model" or NAME=VALUE[,NAME=VALUE...], e.g. "mass=1.5"
    n_episodes: int = 4  # episodes per controller and condition
    data_level: float = 0.1  # the surrogates' training data: perturbation level x U_max
    samples: Optional[int] = None  # sampling MPCs' samples per replan (None: D2C-MPC's budget)
    sampling_sigma: float = 1.0  # the samples' spread, control units
    mppi_temperature: float = 0.01  # MPPI's temperature, a fraction of the first plan's cost
    sampling_knots: int = 0  # 0: samples at every step; k: at k knots, interpolated
    refit_weight: float = 0.0  # > 0: surrogates refitted online, an episode's transition weighing this
    refit_updates: int = 20  # MLP refit: optimiser steps before every replan (0: no MLP refit)
    first_plan: Literal["optimum", "zeros"] = "optimum"  # every planner's first warm start
    n_samples: Optional[int] = None  # D2C-MPC's samples per identification (None: nx + nu)
    sysid_design: Literal["gaussian", "orthogonal"] = "orthogonal"  # D2C-MPC's perturbations


@dataclasses.dataclass(frozen=True)
class ExperimentConfig:
    """What to run and where to write it.

    kind: "rollout" (n_rollouts perturbed rollouts around the task's zero-control
    nominal, with rollout_sigma_x / rollout_sigma_u), "d2c" (data-driven iLQR
    against the exact-Jacobian oracle, then feedback evaluation under noise_levels) or
    "predict" (D2C optimum, data sets per level, SINDy / MLP / LTV predictions),
    "analysis" (convergence across seeds, Gram conditioning, variance; section analysis)
    "theory" (exact moments against Monte Carlo and the paper's formulas) or "control"
    (iLQR on each surrogate, judged on the black box against D2C and the exact oracle) or
    "horizon" (identification error against the rollout length, open against closed loop;
    data.levels, data.n_traj rollouts) or "mpc" (receding-horizon control on the black box,
    every controller of section mpc side by side).
    x64: run in float64 (a user's MJCF model always does: float32 round-off swamps the
      perturbations that contacts and servos need; ``model_defaults.default_x64``).
    exact_oracle: also solve from the same start with exact Jacobians (None: on for the
      registered systems, off for a user's MJCF, whose jacfwd oracle can take minutes to
      compile; docs/performance.md).
    oracle: "jacfwd" (jax.jacfwd through the MJX step) or "finite_difference" (central
      differences of the black-box step along each coordinate: cheap to compile, runs on
      every backend).
    video: on a MuJoCo system, write MP4 videos of the optimum (``optimum.mp4``) and of
      the MPC episodes (``mpc_episodes.mp4``), rendered headless (docs/results.md); where
      no GL context can be made the run says so in one line and goes on.
    """

    kind: str = "d2c"  # a registered kind (mjx_surrogate.runs.experiment_kinds.EXPERIMENTS)
    seed: int = 0
    out_dir: str = "runs"
    name: Optional[str] = None
    x64: bool = False
    n_rollouts: int = 256
    rollout_sigma_x: float = 0.01
    rollout_sigma_u: float = 0.1
    exact_oracle: Optional[bool] = None
    oracle: Literal["jacfwd", "finite_difference"] = "jacfwd"
    noise_levels: Tuple[float, ...] = (0.0, 0.01, 0.05, 0.1)
    n_noise_trials: int = 64
    progress: bool = True
    video: bool = True


@dataclasses.dataclass(frozen=True)
class ParallelConfig:
    """Where the batched work runs (docs/scaling.md).

    devices: how many of the visible devices (of every process) the batch axes are spread
      over (None: all of them; 1: one device, nothing sharded).
    distributed: join the processes of a multi-process run with ``jax.distributed`` first.
    coordinator_address, num_processes, process_id: the rendezvous ("host:port" of process
      0, how many processes, this one's index); None: from the environment
      (``JAX_COORDINATOR_ADDRESS``, ``JAX_NUM_PROCESSES``, ``JAX_PROCESS_ID``), else JAX's
      cluster auto-detection (Slurm, Open MPI, Kubernetes...).
    """

    devices: Optional[int] = None
    distributed: bool = False
    coordinator_address: Optional[str] = None
    num_processes: Optional[int] = None
    process_id: Optional[int] = None


@dataclasses.dataclass(frozen=True)
class Config:
    system: SystemConfig = SystemConfig()
    task: TaskConfig = TaskConfig()
    solver: SolverConfig = SolverConfig()
    experiment: ExperimentConfig = ExperimentConfig()
    data: DataConfig = DataConfig()
    surrogate: SurrogateConfig = SurrogateConfig()
    analysis: AnalysisConfig = AnalysisConfig()
    mpc: MPCConfig = MPCConfig()
    parallel: ParallelConfig = ParallelConfig()
    # the settings of registered extensions, "<section>.<name>" -> values
    # (mjx_surrogate.runs.extension_settings); the command line sets them as
    # --solver.<scheme>.<field>, --surrogate.<kind>.<field>, --experiment.<kind>.<field>
    extensions: Annotated[Dict[str, Any], tyro.conf.Suppress] = dataclasses.field(default_factory=dict)


def to_dict(cfg: Any) -> dict:
    """Config -> nested dict (tuples become lists); written with
    :func:`mjx_surrogate.runs.results.jsonable`, which keeps non-finite numbers loadable."""
    return dataclasses.asdict(cfg)


def _convert(value: Any, hint: Any, field: str) -> Any:
    origin = typing.get_origin(hint)
    args = typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        inner = [a for a in args if a is not type(None)]
        return _convert(value, inner[0], field)
    if origin is Literal:
        if value not in args:
            raise ConfigError(field, f"got {value!r}; valid: {', '.join(map(repr, args))}")
        return value
    if origin in (tuple, Tuple):
        if not isinstance(value, (list, tuple)):
            raise ConfigError(field, f"expected a list, got {value!r}")
        elem = args[0]
        return tuple(_convert(v, elem, f"{field}[{i}]") for i, v in enumerate(value))
    if dataclasses.is_dataclass(hint):
        return from_dict(hint, value, field)
    if hint is bool:
        if not isinstance(value, bool):
            raise ConfigError(field, f"expected true/false, got {value!r}")
        return value
    if hint is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(field, f"expected an integer, got {value!r}")
        return value
    if hint is float:
        if isinstance(value, str) and value in ("nan", "inf", "-inf"):
            return float(value)  # how run folders write non-finite numbers
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(field, f"expected a number, got {value!r}")
        return float(value)
    if hint is str:
        if not isinstance(value, str):
            raise ConfigError(field, f"expected a string, got {value!r}")
        return value
    return value


def from_dict(cls: type, data: Any, prefix: str = "", complete: bool = False) -> Any:
    """Nested dict (e.g. a run's config.json) -> config dataclass, strictly checked.

    complete: every field must be present (a run's config.json names them all; a missing
    one means a config from another version of the schema, reported rather than filled).
    """
    where = prefix or cls.__name__
    if not isinstance(data, dict):
        raise ConfigError(where, f"expected a mapping, got {type(data).__name__}")
    hints = typing.get_type_hints(cls)
    names = [f.name for f in dataclasses.fields(cls)]
    kwargs = {}
    for key, value in data.items():
        field = f"{prefix}.{key}" if prefix else key
        if key not in names:
            raise ConfigError(field, f"unknown field; valid: {', '.join(names)}")
        hint = hints[key]
        if complete and dataclasses.is_dataclass(hint):
            kwargs[key] = from_dict(hint, value, field, complete)
        else:
            kwargs[key] = _convert(value, hint, field)
    missing = [n for n in names if n not in data and n != "extensions"]  # older runs had none
    if complete and missing:
        raise ConfigError(
            prefix or "CONFIG",
            f"missing field(s) {', '.join(missing)}: a config from another schema version; "
            "add them or start from a preset",
        )
    return cls(**kwargs)


def check_finite(field: str, values: Any) -> None:
    """Raise if a (nested) sequence of numbers holds NaN or inf."""
    flat = (
        values
        if not values or not isinstance(values[0], (list, tuple))
        else [v for row in values for v in row]
    )
    for v in flat:
        if not math.isfinite(v):
            raise ConfigError(field, f"holds a non-finite value ({v}); all entries must be finite")


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
        raise ConfigError("mpc.controllers", f"give one or more of {', '.join(MPC_CONTROLLERS)}")
    for i, c in enumerate(m.controllers):
        if c not in MPC_CONTROLLERS:
            raise ConfigError(
                f"mpc.controllers[{i}]", f"unknown controller {c!r}; valid: {', '.join(MPC_CONTROLLERS)}"
            )
    if len(set(m.controllers)) < len(m.controllers):
        raise ConfigError("mpc.controllers", "names a controller twice")
    for field in ("horizon", "steps", "max_iter", "n_episodes"):
        v = getattr(m, field)
        if v is not None and v < 1:
            raise ConfigError(f"mpc.{field}", f"must be >= 1, got {v}")
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
    if m.n_samples is not None and m.n_samples < 1:
        raise ConfigError("mpc.n_samples", f"must be >= 1 (None: nx + nu), got {m.n_samples}")
    if m.first_plan not in ("optimum", "zeros"):
        raise ConfigError("mpc.first_plan", f"one of optimum, zeros, got {m.first_plan!r}")
    if m.sysid_design not in ("gaussian", "orthogonal"):
        raise ConfigError("mpc.sysid_design", f"one of gaussian, orthogonal, got {m.sysid_design!r}")


_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._+-]{0,99}$")


def validate_static(cfg: Config) -> None:
    """Checks that need no model: types, choices, signs, ranges, finiteness, names."""
    _check_types(cfg)
    _check_experiment(cfg.experiment)
    _check_parallel(cfg.parallel)
    _check_mpc(cfg.mpc)
    _check_solver(cfg.solver)
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
    if s.n_samples is not None and s.n_samples < 1:
        raise ConfigError("solver.n_samples", f"must be >= 1 (or unset), got {s.n_samples}")
    _at_least(0, {"solver.reuse_max": s.reuse_max, "solver.stationary_restarts": s.stationary_restarts})
    _at_least(
        1, {"solver.max_iter": s.max_iter, "solver.n_alphas": s.n_alphas, "solver.n_starts": s.n_starts}
    )
    positive = {
        "solver.sigma_x": _SYSID.sigma_x if s.sigma_x is None else s.sigma_x,
        "solver.sigma_u": _SYSID.sigma_u if s.sigma_u is None else s.sigma_u,
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
            "solver.sysid_noise_floor": 0.0 if s.sysid_noise_floor is None else s.sysid_noise_floor,
            "solver.sysid_significance": s.sysid_significance,
            "solver.sysid_rank_tol": s.sysid_rank_tol,
        }
    )


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
    from mjx_surrogate.identification.sysid import SCHEMES, get_scheme
    from mjx_surrogate.runs.experiment_kinds import get_experiment
    from mjx_surrogate.runs.extension_settings import check_extensions
    from mjx_surrogate.surrogates.registry import get_surrogate

    get_experiment(cfg.experiment.kind)

    scheme = get_scheme(cfg.solver.sysid, "solver.sysid")
    if cfg.solver.sysid_every < 1:
        raise ConfigError("solver.sysid_every", f"must be >= 1, got {cfg.solver.sysid_every}")
    if cfg.solver.sysid_every > 1 and not scheme.one_step:
        one_step = ", ".join(n for n, s in SCHEMES.items() if s.one_step)
        raise ConfigError(
            "solver.sysid_every",
            f"> 1 needs a one-step scheme ({one_step}); {cfg.solver.sysid!r} identifies from rollouts",
        )
    if cfg.solver.sysid_significance > 0 and not scheme.t_test:
        tested = ", ".join(n for n, s in SCHEMES.items() if s.t_test)
        raise ConfigError(
            "solver.sysid_significance",
            f"needs a scheme with a t-test ({tested}); {cfg.solver.sysid!r} has none: give 0",
        )
    if cfg.solver.sysid_rank_tol >= 1:
        raise ConfigError("solver.sysid_rank_tol", f"must be in [0, 1), got {cfg.solver.sysid_rank_tol}")
    if cfg.solver.sysid_rank_tol != _SYSID.rank_tol and not scheme.reduced:
        reduced = ", ".join(n for n, s in SCHEMES.items() if s.reduced)
        raise ConfigError(
            "solver.sysid_rank_tol",
            f"only a reduced scheme ({reduced}) has a basis; {cfg.solver.sysid!r} has none",
        )
    if cfg.solver.sysid_design != "gaussian" and not scheme.one_step:
        raise ConfigError(
            "solver.sysid_design",
            f"{cfg.solver.sysid_design!r} needs a one-step scheme; "
            f"{cfg.solver.sysid!r} draws its own perturbations",
        )
    if not cfg.surrogate.kinds:
        raise ConfigError("surrogate.kinds", "give one or more surrogate kinds")
    for i, name in enumerate(cfg.surrogate.kinds):
        get_surrogate(name, f"surrogate.kinds[{i}]")
    check_extensions(cfg)


def _check_function_system(sy: SystemConfig) -> None:
    """A function black box (system.entry, lorenz, f8) has no MuJoCo settings."""
    from mjx_surrogate.systems.registry import USER_FUNCTION, is_function_system

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
