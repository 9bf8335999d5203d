"""The ``solver`` and ``sysid`` sections: the iLQR settings, with ``ILQRParams``' names
and defaults, and how the local models are identified, with ``SysIdParams``'."""

from __future__ import annotations

import dataclasses
import math
from typing import Literal, Optional

from mjx_surrogate.control.ilqr import ILQRParams
from mjx_surrogate.errors import ConfigError
from mjx_surrogate.identification.sysid import SysIdParams
from mjx_surrogate.runs.config.checks import at_least, nonnegative

_ILQR, _SYSID = ILQRParams(), SysIdParams()


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
    # ... and where a single start's ends stalled, solved again from this many starts spread
    # around its start at a quarter of each actuator's half range, the cheapest kept
    # (runs.restart.restart_stalled); None: model_defaults.default_stall_restarts; 0: off
    stall_restarts: Optional[int] = None
    # then, with H > 0, a receding-horizon pass: D2C-MPC over H steps on the model from the
    # kept solve, D2C again from its closed loop, the cheaper kept (runs.receding_pass); 0: off
    receding_pass: int = 0

    def check(self) -> None:
        """Refuses bad values (ConfigError naming the field); the model strategy's name is
        checked against its registry by :func:`mjx_surrogate.runs.validation.validate_static`."""
        for field, v in (("accept_ratio", self.accept_ratio), ("alpha_factor", self.alpha_factor)):
            if not (math.isfinite(v) and 0 < v < 1):
                raise ConfigError(f"solver.{field}", f"must be in (0, 1), got {v}")
        at_least(
            0,
            {
                "solver.reuse_max": self.reuse_max,
                "solver.stationary_restarts": self.stationary_restarts,
                **({} if self.stall_restarts is None else {"solver.stall_restarts": self.stall_restarts}),
                "solver.sampling_search": self.sampling_search,
                "solver.receding_pass": self.receding_pass,
            },
        )
        at_least(
            1,
            {
                "solver.max_iter": self.max_iter,
                "solver.n_alphas": self.n_alphas,
                "solver.n_starts": self.n_starts,
            },
        )
        for field, v in {"solver.mu_max": self.mu_max, "solver.mu_factor": self.mu_factor - 1.0}.items():
            if not (math.isfinite(v) and v > 0):
                raise ConfigError(field, f"must be a finite positive number, got {v}")
        nonnegative(
            {
                "solver.sysid_refine_tol": self.sysid_refine_tol,
                "solver.reuse_tol": self.reuse_tol,
                "solver.rel_tol": self.rel_tol,
                "solver.k_tol": self.k_tol,
                "solver.init_scale": self.init_scale,
                "solver.mu_init": self.mu_init,
                "solver.mu_min": self.mu_min,
                "solver.mu_raise_alpha": self.mu_raise_alpha,
            }
        )


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

    def check(self) -> None:
        """Refuses bad values (ConfigError naming the field); what the scheme supports (the
        t-test, a basis, designs) is checked against its registry by
        :func:`mjx_surrogate.runs.validation.validate_static`."""
        if self.n_samples is not None and self.n_samples < 1:
            raise ConfigError("sysid.n_samples", f"must be >= 1 (or unset), got {self.n_samples}")
        if self.every < 1:
            raise ConfigError("sysid.every", f"must be >= 1, got {self.every}")
        for field in ("sigma_x", "sigma_u"):
            v = getattr(self, field)
            if v is not None and not (math.isfinite(v) and v > 0):
                raise ConfigError(f"sysid.{field}", f"must be a finite positive number (or unset), got {v}")
        nonnegative(
            {
                "sysid.noise_floor": 0.0 if self.noise_floor is None else self.noise_floor,
                "sysid.significance": self.significance or 0.0,
                "sysid.rank_tol": self.rank_tol,
            }
        )
        if self.rank_tol >= 1:
            raise ConfigError("sysid.rank_tol", f"must be in [0, 1), got {self.rank_tol}")
