"""The ``mpc`` section: closed-loop control with receding-horizon planners."""

from __future__ import annotations

import dataclasses
import math
from typing import Literal, Optional, Tuple

from mjx_surrogate.errors import ConfigError


@dataclasses.dataclass(frozen=True)
class MPCSysIdConfig:
    """D2C-MPC's identification at every replan, where it differs from the ``sysid``
    section's (whose perturbation sizes, noise floor and t-test it keeps); the fields are
    ``SysIdParams`` fields of the same name."""

    scheme: Optional[str] = None  # None: sysid.scheme
    n_samples: Optional[int] = None  # None: nx + nu with a one-step scheme, else sysid.n_samples
    design: Literal["gaussian", "orthogonal"] = "orthogonal"  # with nx + nu samples: a diagonal Gram
    every: int = 1  # identify every k-th step of the horizon, interpolate between

    def check(self) -> None:
        """Refuses bad values (ConfigError naming the field)."""
        if self.every < 1:
            raise ConfigError("mpc.sysid.every", f"must be >= 1, got {self.every}")
        if self.n_samples is not None and self.n_samples < 1:
            raise ConfigError("mpc.sysid.n_samples", f"must be >= 1 (None: nx + nu), got {self.n_samples}")
        if self.design not in ("gaussian", "orthogonal"):
            raise ConfigError("mpc.sysid.design", f"one of gaussian, orthogonal, got {self.design!r}")


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

    def check(self) -> None:
        """Refuses bad values and unknown planners or plants (ConfigError naming the field)."""
        from mjx_surrogate.control.planners import PLANNERS, get_planner
        from mjx_surrogate.systems.plant import parse_plant, plant_label

        if not self.controllers:
            raise ConfigError("mpc.controllers", f"give one or more of {', '.join(PLANNERS)}")
        for i, c in enumerate(self.controllers):
            get_planner(c, f"mpc.controllers[{i}]")
        if len(set(self.controllers)) < len(self.controllers):
            raise ConfigError("mpc.controllers", "names a controller twice")
        for field in ("horizon", "steps", "max_iter", "n_episodes", "n_alphas"):
            v = getattr(self, field)
            if v is not None and v < 1:
                raise ConfigError(f"mpc.{field}", f"must be >= 1, got {v}")
        self.sysid.check()
        if self.samples is not None and self.samples < 2:
            raise ConfigError(
                "mpc.samples", f"must be >= 2 (the warm start and one sample), or unset, got {self.samples}"
            )
        if not self.process_noise:
            raise ConfigError("mpc.process_noise", "give one or more levels (0.0: none)")
        for i, v in enumerate(self.process_noise):
            if not (math.isfinite(v) and v >= 0):
                raise ConfigError(f"mpc.process_noise[{i}]", f"must be a finite number >= 0, got {v}")
        if not self.plants:
            raise ConfigError("mpc.plants", "give one or more plants ('model': the model itself)")
        labels = [plant_label(parse_plant(p, f"mpc.plants[{i}]")) for i, p in enumerate(self.plants)]
        if len(set(labels)) < len(labels):
            raise ConfigError("mpc.plants", f"names a plant twice: {', '.join(labels)}")
        if not (math.isfinite(self.data_level) and 0 < self.data_level <= 1):
            raise ConfigError(
                "mpc.data_level", f"must be in (0, 1] (a fraction of U_max), got {self.data_level}"
            )
        for field in ("sampling_sigma", "mppi_temperature"):
            v = getattr(self, field)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError(f"mpc.{field}", f"must be a finite positive number, got {v}")
        if not (math.isfinite(self.refit_weight) and self.refit_weight >= 0):
            raise ConfigError(
                "mpc.refit_weight",
                f"must be a finite number >= 0 (0: no online refit), got {self.refit_weight}",
            )
        if self.refit_updates < 0:
            raise ConfigError(
                "mpc.refit_updates", f"must be >= 0 (0: MLPs not refitted online), got {self.refit_updates}"
            )
        if self.sampling_knots < 0:
            raise ConfigError(
                "mpc.sampling_knots", f"must be >= 0 (0: every step its own draw), got {self.sampling_knots}"
            )
        if self.first_plan not in ("optimum", "zeros", "reference"):
            raise ConfigError("mpc.first_plan", f"one of optimum, zeros, reference, got {self.first_plan!r}")
        if not (math.isfinite(self.realtime_speed) and self.realtime_speed > 0):
            raise ConfigError(
                "mpc.realtime_speed",
                f"the real-time loop's clock, > 0 (1: real time), got {self.realtime_speed}",
            )
        if self.realtime and not any(get_planner(c).replans is not None for c in self.controllers):
            live = [c for c in PLANNERS if get_planner(c).replans is not None]
            raise ConfigError(
                "mpc.realtime",
                f"runs replanning planners in the wall-clock loop: add one of {', '.join(live)}",
            )
