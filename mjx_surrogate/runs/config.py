"""Frozen dataclass configs: system, task, solver, sysid and experiment sections.

A config is plain data. ``resolve`` (in :mod:`mjx_surrogate.runs.resolution`) turns it into a
system, a task and a fully resolved config; every check there raises
:class:`~mjx_surrogate.errors.ConfigError` naming the field, before any XLA compile.
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from typing import Annotated, Any, Dict, Literal, Optional, Tuple

import tyro

from mjx_surrogate.control.ilqr import ILQRParams
from mjx_surrogate.errors import ConfigError
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

    Adds 1/2 weight |p_t - target_t|^2 to every running cost and 1/2 final_weight
    |p_T - target_T|^2 to the terminal cost; p comes from the model's kinematics, the
    dynamics stay a black box. The target starts at ``target`` and moves
    (``mjx_surrogate.moving_targets``): at ``velocity`` (m/s) plus, with ``orbit_radius``
    > 0, round a circle of that radius (m) through its start in ``orbit_plane``, once per
    ``orbit_period`` (s); time counts from the episode's start, in closed loop too.
    """

    name: str = ""
    target: Tuple[float, ...] = (0.0, 0.0, 0.0)
    weight: float = 0.0
    final_weight: float = 1.0
    kind: Literal["site", "body"] = "site"
    velocity: Tuple[float, ...] = (0.0, 0.0, 0.0)
    orbit_radius: float = 0.0
    orbit_period: float = 1.0
    orbit_plane: Literal["xy", "xz", "yz"] = "xy"


@dataclasses.dataclass(frozen=True)
class TaskConfig:
    """Start, goal, horizon and quadratic weights (cost convention in docs/results.md).

    preset: a task preset (see ``mjx_surrogate.systems.task_presets()``) filling every
    field left as None; "hold" (any model: keep the start, qpos0 or x0_keyframe, for 50
    control steps; ``model_defaults.hold_task``); or "custom" (then x_goal, T and weights
    are required).
    Q, Q_f, R: full matrices; Q_diag, Q_f_diag, R_diag: diagonal shortcuts (Q and Q_f
      given as diagonals stay diagonals: no nx x nx array for a grid of many cells).
    u_min, u_max: box limits on the controls, enforced by the solver; by default the
      preset's, else the model's actuator ctrlrange, which they may narrow but not widen.
    x0_keyframe, goal_keyframe: a keyframe of the model (name or index) giving x0, or
      x_goal and the control reference u_ref (its ctrl).
    u_ref: the control the R term pulls towards (default zeros).
    state_error: "euclidean" (x - x_goal), "geodesic" (hinge angles wrapped to
      (-pi, pi], quaternions by their rotation vector) or "chordal" (as geodesic, but each
      hinge's error d measured by its chord 2 sin(d / 2): the angle costs 2 (1 - cos d),
      hydrax's swing-up cost); None: the preset's, else geodesic.
    goals: PointGoal terms on sites or bodies, added to the quadratic cost.
    hessian: the solver's Hessian of the point goals and of a chordal error: "gauss_newton"
      (J'WJ of their residuals, MuJoCo MPC's treatment; positive semi-definite) or "exact"
      (second derivatives throughout; the chordal angle term's is negative below the
      horizontal, docs/mpc.md).
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
    state_error: Optional[Literal["euclidean", "geodesic", "chordal"]] = None
    goals: Tuple[PointGoal, ...] = ()
    goal_tolerance: float = 0.01
    hessian: Literal["gauss_newton", "exact"] = "gauss_newton"


@dataclasses.dataclass(frozen=True)
class SolverConfig:
    """iLQR and data-driven (D2C) iLQR settings.

    Every field but the search's (init ... receding_pass) is an ``ILQRParams`` field of
    the same name; how the local models are identified is the ``sysid`` section.

    sysid_refine_tol: with sysid.every > 1, identify at every step from the first accepted
    step that gains at most this fraction of the cost, or where the solver would have
    stopped (0: only there); minima are declared on every-step models only.
    mu_raise_alpha: a step accepted only at a size below this raises mu (up to mu_max)
    instead of lowering it: a trust region on the step (``mjx_surrogate.control.ilqr``); 0: off.
    reuse_tol, reuse_max: after an accepted step whose actual decrease was within reuse_tol
    of the model's promise, carry the model over (secant update) instead of identifying,
    at most reuse_max iterations in a row (``mjx_surrogate.control.model_strategies``); 0: always identify.
    model_strategy: when the model is identified: "default" (every iteration where the
    nominal moved, with the reuse and coarse-then-fine settings above) or a strategy
    registered with ``mjx_surrogate.control.model_strategies.register_model_strategy``.
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
    sysid_refine_tol: float = _ILQR.sysid_refine_tol  # sysid.every > 1: every step once a step gains <= this
    reuse_tol: float = _ILQR.reuse_tol  # carry the model over when |ratio - 1| <= this
    reuse_max: int = _ILQR.reuse_max  # ... at most this many iterations in a row
    # when the model is identified: a registered strategy (control.model_strategies)
    model_strategy: str = _ILQR.model_strategy
    init: Optional[Literal["zeros", "random", "u_ref", "hold"]] = None  # None: model_defaults.default_init
    init_scale: float = 0.1
    n_starts: int = 1
    # a kept solve (one start's, or the cheapest of n_starts) that ends stationary or stalled
    # short of its goal: this many rounds of the cross-entropy method on the black box, then
    # D2C from its plan (runs.sampling_search); 0: off
    sampling_search: int = 20
    # ... and where a single start's is still stationary, solved again from this many starts
    # spread over the actuators' range (mjx_surrogate.runs.restart); 0: off
    stationary_restarts: int = 8
    # then, with H > 0, a receding-horizon pass: D2C-MPC over H steps on the model from the
    # kept solve, D2C again from its closed loop, the cheaper kept (runs.receding_pass); 0: off
    receding_pass: int = 0


@dataclasses.dataclass(frozen=True)
class SysIdConfig:
    """How the local LTV models are identified: every field is the ``SysIdParams`` field of
    the same name (None: resolved from the model, ``mjx_surrogate.runs.model_defaults``).

    scheme: a registered identification scheme: "central_difference" (D2C 2.0's one-step
      scheme), "forward_difference" (one-sided, half the simulator calls, first-order
      accurate), "rollout" (the paper's open-loop perturbed rollouts), "closed_loop"
      (perturbed rollouts under the current feedback gains), "reduced" (RO-D2C for black
      boxes with many states, e.g. PDEs: a snapshot basis of n_samples rollouts and central
      differences in it, ``mjx_surrogate.identification.sysid_reduced``), or one registered
      with ``mjx_surrogate.identification.sysid.register_scheme`` (its own settings:
      ``--sysid.<scheme>.<field>``).
    every: with a one-step scheme, identify only every k-th time step (and the last) and
      interpolate linearly between (``mjx_surrogate.identification.sysid_knots``).
    design: a one-step scheme's perturbations: "gaussian" (D2C 2.0: i.i.d. N(0, sigma^2))
      or "orthogonal" (blocks of nx + nu orthogonal rows: with n_samples = nx + nu the
      fewest samples, perfectly conditioned).
    rank_tol: with a reduced scheme, the fraction of the snapshots' energy the basis may
      leave out (its rank is at most n_samples).
    """

    scheme: str = _SYSID.scheme  # a registered scheme (mjx_surrogate.identification.sysid.SCHEMES)
    n_samples: Optional[int] = None  # None: max(20, 2 (nx + nu)); reduced: min(nx, max(16, 4 nu))
    sigma_x: Optional[float] = None  # perturbation std of the states (None: model_defaults.default_sigma)
    sigma_u: Optional[float] = None  # ... of the controls
    every: int = _SYSID.every  # one-step schemes: identify every k-th step, interpolate between
    design: Literal["gaussian", "orthogonal"] = "gaussian"  # one-step perturbations
    noise_floor: Optional[float] = None  # zero entries below c eps |x| / sigma (None: model_defaults)
    perturb_x0: Optional[bool] = None  # one-step schemes perturb the given start (None: model_defaults)
    hold_limits: Optional[bool] = None  # one-step schemes hold joints at a limit (None: model_defaults)
    # zero identified coefficients with |t| <= this (0: off; None: model_defaults.default_significance)
    significance: Optional[float] = None
    rank_tol: float = _SYSID.rank_tol  # reduced scheme: energy the snapshot basis leaves out


@dataclasses.dataclass(frozen=True)
class MPCSysIdConfig:
    """D2C-MPC's identification at every replan, where it differs from the ``sysid``
    section's (whose perturbation sizes, noise floor and t-test it keeps); the fields are
    ``SysIdParams`` fields of the same name."""

    scheme: Optional[str] = None  # None: sysid.scheme
    n_samples: Optional[int] = None  # None: nx + nu with a one-step scheme, else sysid.n_samples
    design: Literal["gaussian", "orthogonal"] = "orthogonal"  # with nx + nu samples: a diagonal Gram
    every: int = 1  # identify every k-th step of the horizon, interpolate between


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
    stops earlier once the best held-out loss fell by less than stop_rel_tol (relative) over
    the last stop_window epochs (the convergence test). patience > 0: early stopping on a
    validation set of whole trajectories (validation_fraction of the training ones): stop
    once its loss has not improved for patience epochs and keep the best epoch's network.
    fixed_epochs_beside N > 0: also fit the paper's network (all training data, exactly N
    epochs, the same initialisation), labelled "MLP N epochs"."""

    widths: Tuple[int, ...] = (32, 64)
    learning_rate: float = 1e-4
    weight_decay: float = 1e-6
    batch_size: int = 256
    epochs: int = 200
    checkpoints: Tuple[int, ...] = ()
    stop_window: int = 0
    stop_rel_tol: float = 0.0
    patience: int = 0
    validation_fraction: float = 0.1
    fixed_epochs_beside: int = 0


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
      snapshot basis per t (energy rule as sysid.rank_tol), "LTV reduced": for black
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


# the built-in planners (mjx_surrogate.control.planners), in the order a study runs them
MPC_CONTROLLERS = ("d2c", "oracle", "tvlqr", "surrogates", "predictive_sampling", "mppi", "cem")


@dataclasses.dataclass(frozen=True)
class MPCConfig:
    """Receding-horizon control on the black box (kind "mpc", docs/mpc.md).

    controllers: from "d2c" (LTV models identified at every replan), "oracle" (exact
      Jacobians: experiment.oracle; only where experiment.exact_oracle is on), "tvlqr"
      (tracking the offline D2C optimum, no replanning), "surrogates" (iLQR on every
      model of surrogate.kinds, fitted on data.n_traj trajectories around the optimum at
      data_level), "predictive_sampling", "mppi" and "cem" (derivative-free, on the black
      box; each with its own settings, --mpc.<planner>.<field>: spline, iterations, the
      spread's units; mjx_surrogate.control.sampling_planners); not by default,
      "d2c_sampling" (D2C-MPC from the best of its warm start and sampled proposals).
    horizon: control steps per plan H (None: task.T). steps: control steps of an episode
      (None: task.T; at most task.T with "tvlqr"). max_iter: iLQR iterations per replan.
    replan_hz: how often every planner replans, per second of the system's time (None:
      at every control step); 1 / (replan_hz control_dt) must be a whole number r of
      control steps dividing mpc.steps. Between replans the plant steps at its own rate
      under the last plan: its controls with its feedback gains (iLQR planners,
      u = U[j] + K[j] (x - X[j]), clipped to the limits) or its controls alone (sampling
      planners), as MuJoCo MPC's agent and hydrax's simulation loop run them.
    horizon_end: where a plan made at control step n ends: "task" at the task's end when
      that comes first (stage min(task.T - n, H): the horizon shrinks to it, the terminal
      cost stays at the task's end, only the control effort counts after it; needs steps
      <= task.T), "receding" H steps ahead (the terminal cost at every plan's end, moving
      with it), "auto": "task" where steps <= task.T, else "receding". Every planner
      plans on the same horizon; the run records which one and why (mpc_horizon_end).
    process_noise: standard deviations (state units) of the noise added after every plant
      step, one set of episodes per level. plants: the black boxes the episodes run on,
      each "model" (the controller's own) or changes NAME=VALUE[,NAME=VALUE...]: on a
      MuJoCo model scale factors of mass (masses and inertias), length (body geometry,
      masses kept), damping (joint damping) or gravity, e.g. "mass=1.5,damping=2"; on a
      function black box keyword arguments of the function that builds it, e.g. "rho=30"
      for Lorenz (docs/mpc.md).
    n_episodes: episodes per controller and condition (their own keys).
    samples: samples per replan of the sampling MPCs (None: matched to D2C-MPC's median
      black-box steps per control step, divided by their iterations, else 64).
      sampling_sigma: their starting spread (in each planner's sigma_units: by default
      each actuator's half range where its limits are finite, else control units).
      mppi_temperature: MPPI's temperature as a fraction of the first plan's cost (unless
      its own settings give one in cost units). sampling_knots: 0 gives every control
      step its own value; k >= 1 holds each plan at k knots spread over the horizon, read
      through the planner's spline (zero, linear or cubic; hydrax's spline planners; at
      most the horizon). Each sampling planner's own settings may override these.
    refit_weight: > 0 adds, for every SINDy model, SINDy-MPC refitted online before every
      replan on its training transitions and the episode's own, each of these weighing
      refit_weight training ones (``mpc_online``; SINDy-MPC's low-data setting); 0: off.
      refit_updates: with refit_weight > 0, MLP-MPC refitted online too: the network takes
      this many steps of its own optimiser (surrogate.mlp) on that weighted loss before
      every replan; 0: MLPs are not refitted.
    first_plan: every planner's first warm start: "optimum" (the offline D2C optimum's
      first H controls), "zeros", or "reference" (the task's u_ref at every step: for a
      hold task the controls that hold its start).
    sysid: D2C-MPC's identification at every replan (``MPCSysIdConfig``; the sysid
      section's perturbation sizes otherwise): its scheme (None: sysid.scheme;
      "forward_difference" simulates nx + nu + 1 steps per stage where central differences
      simulate 2 (nx + nu), as MuJoCo MPC's finite differences do), samples per
      identification (None: nx + nu with a one-step scheme, the fewest that determine
      [A_t B_t]; else sysid.n_samples) in its design ("orthogonal": with nx + nu samples
      the Gram matrix is exactly diagonal, paper Section 3; "gaussian": D2C 2.0's), and
      ``every``: identify at every k-th step of the horizon and its last one, linearly
      interpolated between (MuJoCo MPC's derivative skip; one-step schemes; the replans
      never hand over to every-step models). The offline optimum keeps the sysid section.
    realtime: every replanning planner's episodes of every condition (D2C-MPC, the oracle's
      MPC, MPC on each surrogate, the sampling planners, the hybrid; not TVLQR tracking or the
      online refits) run again, one by one, in the wall-clock loop
      (``mjx_surrogate.control.realtime``: the plant at its control period, the planner in a
      thread of its own, each plan applied by its time stamp), with the batch's keys: a row
      "<planner> in real time" each (how late its plans were applied, the planner's pace).
      realtime_speed: that loop's clock (1: real time; 0.5: the plant at half speed).
    n_alphas: line-search step sizes per replan iteration (None: solver.n_alphas).
    """

    controllers: Tuple[str, ...] = (
        MPC_CONTROLLERS  # d2c, oracle, tvlqr, surrogates, predictive_sampling, mppi, cem
    )
    horizon: Optional[int] = None  # control steps per plan H (None: task.T)
    steps: Optional[int] = None  # control steps of an episode (None: task.T)
    max_iter: int = 5  # iLQR iterations per replan
    horizon_end: Literal["auto", "task", "receding"] = "auto"  # plans end at the task's end, or H ahead
    replan_hz: Optional[float] = None  # replans per second (None: every control step)
    process_noise: Tuple[float, ...] = (0.0, 0.01)  # noise std added after each plant step, per level
    plants: Tuple[str, ...] = ("model",)  # "model" or NAME=VALUE[,NAME=VALUE...], e.g. "mass=1.5"
    n_episodes: int = 4  # episodes per controller and condition
    data_level: float = 0.1  # the surrogates' training data: perturbation level x U_max
    samples: Optional[int] = None  # sampling MPCs' samples per replan (None: D2C-MPC's budget)
    sampling_sigma: float = 1.0  # the samples' starting spread (each planner's sigma_units)
    mppi_temperature: float = 0.01  # MPPI's temperature, a fraction of the first plan's cost
    sampling_knots: int = 0  # 0: every step its own value; k: plans held at k knots
    refit_weight: float = 0.0  # > 0: surrogates refitted online, an episode's transition weighing this
    refit_updates: int = 20  # MLP refit: optimiser steps before every replan (0: no MLP refit)
    first_plan: Literal["optimum", "zeros", "reference"] = "optimum"  # every planner's first warm start
    realtime: bool = False  # the replanning planners' episodes also in the wall-clock loop, rows of their own
    realtime_speed: float = 1.0  # that loop's clock: 1 is real time, < 1 slower
    sysid: MPCSysIdConfig = MPCSysIdConfig()  # D2C-MPC's identification per replan
    n_alphas: Optional[int] = None  # line-search step sizes per replan iteration (None: the solver's)


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
    sysid: SysIdConfig = SysIdConfig()
    experiment: ExperimentConfig = ExperimentConfig()
    data: DataConfig = DataConfig()
    surrogate: SurrogateConfig = SurrogateConfig()
    analysis: AnalysisConfig = AnalysisConfig()
    mpc: MPCConfig = MPCConfig()
    parallel: ParallelConfig = ParallelConfig()
    # the settings of registered extensions, "<section>.<name>" -> values
    # (mjx_surrogate.runs.extension_settings); the command line sets them as
    # --sysid.<scheme>.<field>, --solver.<strategy>.<field>, --surrogate.<kind>.<field>,
    # --experiment.<kind>.<field>, --mpc.<planner>.<field>
    extensions: Annotated[Dict[str, Any], tyro.conf.Suppress] = dataclasses.field(default_factory=dict)


# Fields that 0.5.0 moved into the sysid sections (old dotted name -> new): a run folder
# written before keeps replaying (:func:`upgrade`), and an old flag is told where it went.
MOVED = {
    "solver.sysid": "sysid.scheme",
    "solver.n_samples": "sysid.n_samples",
    "solver.sigma_x": "sysid.sigma_x",
    "solver.sigma_u": "sysid.sigma_u",
    "solver.sysid_every": "sysid.every",
    "solver.sysid_design": "sysid.design",
    "solver.sysid_noise_floor": "sysid.noise_floor",
    "solver.sysid_significance": "sysid.significance",
    "solver.sysid_rank_tol": "sysid.rank_tol",
    "solver.sysid_perturb_x0": "sysid.perturb_x0",
    "solver.sysid_hold_limits": "sysid.hold_limits",
    "mpc.sysid": "mpc.sysid.scheme",
    "mpc.n_samples": "mpc.sysid.n_samples",
    "mpc.sysid_design": "mpc.sysid.design",
    "mpc.sysid_every": "mpc.sysid.every",
}


def upgrade(data: dict) -> dict:
    """A config dict of an earlier schema (a run's config.json before 0.5.0) with its
    moved fields (:data:`MOVED`) and its scheme's settings (``solver.<scheme>`` ->
    ``sysid.<scheme>``) where they are now; a current one is returned as it is."""
    solver, mpc = data.get("solver"), data.get("mpc")
    if "sysid" in data or not isinstance(solver, dict) or not isinstance(mpc, dict):
        return data
    out = {k: dict(v) if isinstance(v, dict) else v for k, v in data.items()}
    moved = {"sysid": {}, "mpc.sysid": {}}
    for old, new in MOVED.items():
        section, field = old.split(".")
        if field in out[section]:
            target, name = new.rsplit(".", 1)
            moved[target][name] = out[section].pop(field)
    out["sysid"], out["mpc"]["sysid"] = moved["sysid"], moved["mpc.sysid"]
    scheme = solver.get("sysid")
    if isinstance(out.get("extensions"), dict) and f"solver.{scheme}" in out["extensions"]:
        ext = dict(out["extensions"])
        ext[f"sysid.{scheme}"] = ext.pop(f"solver.{scheme}")
        out["extensions"] = ext
    return out


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
            if field in MOVED:
                raise ConfigError(field, f"moved to {MOVED[field]} in version 0.5.0")
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
