"""The ``task`` section: horizon, costs, start, goal and point goals (:mod:`.goal`)."""

from __future__ import annotations

import dataclasses
import math
from typing import Annotated, Literal, Optional, Tuple

from mjx_surrogate.errors import ConfigError
from mjx_surrogate.runs.config.goal import GOALS_ARG, PointGoal

Vector = Optional[Tuple[float, ...]]
Matrix = Optional[Tuple[Tuple[float, ...], ...]]


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
    goals: Annotated[Tuple[PointGoal, ...], GOALS_ARG] = ()  # KIND:NAME:X,Y,Z... each (--help)
    goal_tolerance: float = 0.01
    hessian: Literal["gauss_newton", "exact"] = "gauss_newton"

    def check(self) -> None:
        """Refuses bad values (ConfigError naming the field); the checks that need the model
        are :mod:`mjx_surrogate.runs.task_resolution`'s."""
        if self.T is not None and self.T < 1:
            raise ConfigError("task.T", f"horizon must be a positive integer, got {self.T}")
        if not (math.isfinite(self.goal_tolerance) and 0 < self.goal_tolerance <= 1):
            raise ConfigError("task.goal_tolerance", f"must be in (0, 1], got {self.goal_tolerance}")
        for i, g in enumerate(self.goals):
            g.check(f"task.goals[{i}]")
