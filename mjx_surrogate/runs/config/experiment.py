"""The ``experiment`` and ``parallel`` sections: what a run does and records, and the
devices and processes it runs on."""

from __future__ import annotations

import dataclasses
import re
from typing import Annotated, Literal, Optional, Tuple

import tyro

from mjx_surrogate.errors import ConfigError
from mjx_surrogate.runs.config.checks import at_least, check_finite, nonnegative

_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._+-]{0,99}$")
_ADDRESS = re.compile(r"^[^\s:]+:\d{1,5}$|^\[[0-9A-Fa-f:.]+\]:\d{1,5}$")


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
    out_dir: Annotated[str, tyro.conf.arg(aliases=("--out",))] = "runs"  # where run folders are made
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

    def check(self) -> None:
        """Refuses bad values (ConfigError naming the field); the kind's name is checked
        against its registry by :func:`mjx_surrogate.runs.validation.validate_static`."""
        if not 0 <= self.seed < 2**31:
            raise ConfigError("experiment.seed", f"must be an integer in [0, 2**31 - 1], got {self.seed}")
        if self.name is not None and (not _NAME.match(self.name) or ".." in self.name):
            raise ConfigError(
                "experiment.name",
                f"got {self.name!r}; use 1-100 letters, digits, '.', '_', '+' or '-' (no '/', no '..')",
            )
        if not self.out_dir:
            raise ConfigError("experiment.out_dir", "must name a directory")
        at_least(
            1, {"experiment.n_rollouts": self.n_rollouts, "experiment.n_noise_trials": self.n_noise_trials}
        )
        nonnegative(
            {
                "experiment.rollout_sigma_x": self.rollout_sigma_x,
                "experiment.rollout_sigma_u": self.rollout_sigma_u,
            }
        )
        check_finite("experiment.noise_levels", self.noise_levels)
        if any(v < 0 for v in self.noise_levels):
            raise ConfigError("experiment.noise_levels", "noise levels must be >= 0")


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

    def check(self) -> None:
        """Refuses bad values (ConfigError naming the field)."""
        if self.devices is not None and self.devices < 1:
            raise ConfigError("parallel.devices", f"must be >= 1 (or unset: all devices), got {self.devices}")
        if self.num_processes is not None and self.num_processes < 1:
            raise ConfigError("parallel.num_processes", f"must be >= 1 (or unset), got {self.num_processes}")
        if self.process_id is not None and not 0 <= self.process_id < (self.num_processes or 2**31):
            raise ConfigError(
                "parallel.process_id", f"must be in [0, num_processes - 1], got {self.process_id}"
            )
        if self.coordinator_address is not None and not _ADDRESS.match(self.coordinator_address):
            raise ConfigError(
                "parallel.coordinator_address", f"must be 'host:port', got {self.coordinator_address!r}"
            )
        given = [
            f for f in ("coordinator_address", "num_processes", "process_id") if getattr(self, f) is not None
        ]
        if given and not self.distributed:
            raise ConfigError(f"parallel.{given[0]}", "only used with parallel.distributed: true")
