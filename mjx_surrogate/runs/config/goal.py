"""Point goals: a goal on the world position of a named site or body, its check, and its
text form on the command line (``--task.goals``, parsed by tyro through :data:`GOALS_ARG`)."""

from __future__ import annotations

import dataclasses
import math
from typing import Literal, Tuple

from tyro.constructors import PrimitiveConstructorSpec

from mjx_surrogate.errors import ConfigError
from mjx_surrogate.runs.config.checks import check_finite, nonnegative

FORM = "KIND:NAME:X,Y,Z[:WEIGHT[:FINAL_WEIGHT]]"
GOALS_HELP = (
    f"--task.goals {FORM} ...: point goals on sites or bodies (KIND site or body; WEIGHT on the "
    "running cost, default 0; FINAL_WEIGHT on the terminal cost, default 1), e.g. --task.goals "
    "site:tip:0.1,0.1,0.01:0:1000; a moving target adds :velocity=VX,VY,VZ (m/s) and/or "
    ":orbit=RADIUS,PERIOD[,PLANE] (a circle through the target, PLANE xy, xz or yz)"
)


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

    def check(self, where: str) -> None:
        """Refuses bad values (ConfigError naming the field under ``where``, e.g. task.goals[0])."""
        if not self.name:
            raise ConfigError(f"{where}.name", f"names the {self.kind} whose position is steered")
        if len(self.target) != 3:
            raise ConfigError(f"{where}.target", f"needs 3 numbers (x, y, z), got {len(self.target)}")
        check_finite(f"{where}.target", self.target)
        nonnegative({f"{where}.weight": self.weight, f"{where}.final_weight": self.final_weight})
        if len(self.velocity) != 3:
            raise ConfigError(f"{where}.velocity", f"needs 3 numbers (m/s), got {len(self.velocity)}")
        check_finite(f"{where}.velocity", self.velocity)
        nonnegative({f"{where}.orbit_radius": self.orbit_radius})
        if not (math.isfinite(self.orbit_period) and self.orbit_period > 0):
            raise ConfigError(f"{where}.orbit_period", f"seconds per turn, > 0, got {self.orbit_period}")
        if self.orbit_plane not in ("xy", "xz", "yz"):
            raise ConfigError(f"{where}.orbit_plane", f"one of xy, xz, yz, got {self.orbit_plane!r}")

    @classmethod
    def from_text(cls, text: str) -> "PointGoal":
        """``KIND:NAME:X,Y,Z[:WEIGHT[:FINAL_WEIGHT]][:velocity=VX,VY,VZ][:orbit=R,P[,PLANE]]``
        -> PointGoal (ConfigError naming task.goals if malformed; NAME may hold ':')."""
        parts = text.split(":")
        motion = {}
        while parts and parts[-1].startswith(("velocity=", "orbit=")):
            motion.update(_motion(text, parts.pop()))
        form = f"{FORM} with KIND site or body"
        at = [i for i, part in enumerate(parts) if "," in part]  # the target
        j = at[-1] if at else -1
        if j < 2 or len(parts) - j > 3 or parts[0] not in ("site", "body") or not ":".join(parts[1:j]):
            raise ConfigError("task.goals", f"{text!r} is not {form}")
        try:
            target = tuple(float(v) for v in parts[j].split(","))
            weights = [float(v) for v in parts[j + 1 :]]
        except ValueError:
            raise ConfigError(
                "task.goals", f"{text!r}: the target and weights must be numbers ({form})"
            ) from None
        if len(target) != 3:
            raise ConfigError("task.goals", f"{text!r}: the target needs 3 numbers X,Y,Z, got {len(target)}")
        weight, final_weight = (weights + [0.0, 1.0][len(weights) :])[:2]
        name = ":".join(parts[1:j])
        return cls(
            name=name, target=target, weight=weight, final_weight=final_weight, kind=parts[0], **motion
        )

    def to_text(self) -> str:
        """The text :meth:`from_text` reads back as this goal."""
        numbers = ",".join(repr(float(v)) for v in self.target)
        text = f"{self.kind}:{self.name}:{numbers}:{float(self.weight)!r}:{float(self.final_weight)!r}"
        if any(v != 0 for v in self.velocity):
            text += ":velocity=" + ",".join(repr(float(v)) for v in self.velocity)
        if self.orbit_radius:
            text += f":orbit={float(self.orbit_radius)!r},{float(self.orbit_period)!r},{self.orbit_plane}"
        return text


def _motion(text: str, part: str) -> dict:
    """``velocity=VX,VY,VZ`` or ``orbit=R,P[,PLANE]`` -> PointGoal fields."""
    key, value = part.split("=", 1)
    values = value.split(",")
    form = "velocity=VX,VY,VZ" if key == "velocity" else "orbit=RADIUS,PERIOD[,PLANE]"
    n = 3 if key == "velocity" else 2
    try:
        numbers = tuple(float(v) for v in values[:n])
    except ValueError:
        raise ConfigError("task.goals", f"{text!r}: {key} must be numbers ({form})") from None
    if len(numbers) != n or len(values) > (3 if key == "orbit" else n):
        raise ConfigError("task.goals", f"{text!r}: {part!r} is not {form}")
    if key == "velocity":
        return {"velocity": numbers}
    plane = values[2] if len(values) == 3 else "xy"
    return {"orbit_radius": numbers[0], "orbit_period": numbers[1], "orbit_plane": plane}


# how tyro reads --task.goals: each token one goal's text form
GOALS_ARG = PrimitiveConstructorSpec(
    nargs="*",
    metavar=FORM,
    instance_from_str=lambda texts: tuple(PointGoal.from_text(t) for t in texts),
    is_instance=lambda v: isinstance(v, tuple) and all(isinstance(g, PointGoal) for g in v),
    str_from_instance=lambda goals: [g.to_text() for g in goals],
)
