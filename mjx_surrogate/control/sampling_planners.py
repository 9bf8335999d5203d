"""The sampling planners of ``mpc.controllers`` (``predictive_sampling``, ``mppi``, ``cem``)
and their own settings (``--mpc.<planner>.<field>``, docs/mpc.md).

Every sampling planner shares ``mpc.samples`` (None: D2C-MPC's budget), ``mpc.sampling_sigma``
and ``mpc.sampling_knots`` unless its own settings give ``samples``, ``sigma`` or ``knots``;
its settings add the spline through the knots, the iterations per replan and the units of
the spread: "range" (default) scales sigma by each actuator's half range (hi - lo) / 2,
where both limits are finite, as MuJoCo MPC and hydrax's +-1 control ranges have it;
"control" takes it in control units. MPPI's ``temperature`` is in cost units (None:
``mpc.mppi_temperature`` times the first plan's cost); CEM keeps ``elites`` draws and a
spread of at least ``sigma_min`` (the spread's units). With ``budget_row``, a planner whose
own ``samples`` are set has a second row beside that one: the same settings at D2C-MPC's
budget (where the run matches it: ``mpc.samples`` unset and D2C-MPC run first).
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any, Literal, Optional

import jax.numpy as jnp
import numpy as np

from mjx_surrogate.control import mpc_sampling, realtime
from mjx_surrogate.control.episode import bound_episode
from mjx_surrogate.control.mpc_sampling import SamplingHyper, SamplingSettings
from mjx_surrogate.errors import ConfigError
from mjx_surrogate.tasks import half_ranges, trajectory_cost
from mjx_surrogate.trajectory import open_loop

PlannerContext = Any  # mjx_surrogate.control.planners.PlannerContext (which imports this module)


@dataclasses.dataclass(frozen=True)
class SamplingPlannerSettings:
    """A sampling planner's own settings (module docstring)."""

    samples: Optional[int] = None  # None: mpc.samples (None there: D2C-MPC's budget)
    sigma: Optional[float] = None  # the starting spread (None: mpc.sampling_sigma)
    sigma_units: Literal["range", "control"] = "range"  # per actuator half range, or control units
    knots: Optional[int] = None  # None: mpc.sampling_knots (0: every control step its own)
    spline: Literal["zero", "linear", "cubic"] = "zero"  # through the knots
    iterations: int = 1  # sample-and-update rounds per replan
    budget_row: bool = False  # with samples set: also a row at D2C-MPC's budget (module docstring)

    def check(self) -> None:
        if self.samples is not None and self.samples < 2:
            raise ConfigError("samples", f"must be >= 2, or unset, got {self.samples}")
        if self.sigma is not None and self.sigma < 0:
            raise ConfigError("sigma", f"must be >= 0, or unset, got {self.sigma}")
        if self.knots is not None and self.knots < 0:
            raise ConfigError("knots", f"must be >= 0 (0: every step its own), or unset, got {self.knots}")
        if self.iterations < 1:
            raise ConfigError("iterations", f"must be >= 1, got {self.iterations}")
        if self.budget_row and self.samples is None:
            raise ConfigError("budget_row", "needs the planner's own samples set")


@dataclasses.dataclass(frozen=True)
class MPPISettings(SamplingPlannerSettings):
    temperature: Optional[float] = None  # cost units (None: mpc.mppi_temperature x the first plan's cost)

    def check(self) -> None:
        super().check()
        if self.temperature is not None and self.temperature <= 0:
            raise ConfigError("temperature", f"must be > 0, or unset, got {self.temperature}")


@dataclasses.dataclass(frozen=True)
class CEMSettings(SamplingPlannerSettings):
    elites: int = 3  # the cheapest draws the distribution is refitted to
    sigma_min: float = 0.1  # the spread's floor, in the spread's units
    explore_fraction: float = 0.0  # of the samples drawn at the starting spread

    def check(self) -> None:
        super().check()
        if self.elites < 1 or (self.samples is not None and self.elites > self.samples):
            raise ConfigError("elites", f"must be between 1 and the samples, got {self.elites}")
        if self.sigma_min < 0:
            raise ConfigError("sigma_min", f"must be >= 0, got {self.sigma_min}")
        if not 0.0 <= self.explore_fraction < 1.0:
            raise ConfigError("explore_fraction", f"must be in [0, 1), got {self.explore_fraction}")


SETTINGS = {
    "predictive_sampling": SamplingPlannerSettings(),
    "mppi": MPPISettings(),
    "cem": CEMSettings(),
}
LABELS = {"predictive_sampling": "predictive sampling", "mppi": "MPPI", "cem": "CEM"}


def spread_scale(lo: np.ndarray, hi: np.ndarray, units: str) -> np.ndarray:
    """[nu]: what the spread is multiplied by: each actuator's half range (hi - lo) / 2 where
    both limits are finite ("range"), else 1 (control units)."""
    return half_ranges(lo, hi) if units == "range" else np.ones(np.shape(lo))


def own_settings(c: PlannerContext, name: str) -> SamplingPlannerSettings:
    """Planner ``name``'s own settings in the run (its defaults where the run gives none)."""
    return c.planner_settings.get(name, SETTINGS.get(name, SamplingPlannerSettings()))


def resolved(c: PlannerContext, name: str, own: SamplingPlannerSettings | None = None):
    """(SamplingSettings, SamplingHyper, the planner's settings) of planner ``name`` in
    context ``c``: its own settings (``own``, else the run's) over the ``mpc`` section's
    shared ones."""
    m, own = c.config.mpc, own or own_settings(c, name)
    samples = own.samples or c.samples
    if own.samples is None and c.samples_matched:  # the budget per replan, over its iterations
        samples = max(2, int(round(c.samples / own.iterations)))
    task = c.plan_task
    scale = spread_scale(task.u_min, task.u_max, own.sigma_units)
    sigma = (m.sampling_sigma if own.sigma is None else own.sigma) * scale
    temperature, elites, explore, sigma_min = 1.0, 1, 0, 0.0 * scale
    if name == "mppi":
        if own.temperature is not None:
            temperature = own.temperature
        else:
            first = open_loop(c.system.step, task.x0, c.U0, task.u_min, task.u_max)
            temperature = m.mppi_temperature * float(trajectory_cost(task, *first))
    if name == "cem":
        elites, explore, sigma_min = own.elites, int(samples * own.explore_fraction), own.sigma_min * scale
    settings = SamplingSettings(
        rule=name,
        samples=samples,
        knots=m.sampling_knots if own.knots is None else own.knots,
        spline=own.spline,
        iterations=own.iterations,
        elites=min(elites, samples),
        explore=explore,
    )
    dtype = task.x0.dtype
    hyper = SamplingHyper(*(jnp.asarray(v, dtype) for v in (sigma, temperature, sigma_min)))
    return settings, hyper, own


def label(name: str, s: SamplingSettings, own: SamplingPlannerSettings) -> str:
    """The planner's row label: its name, samples and the settings that shape its plans."""
    parts = [f"S={s.samples}"]
    if s.iterations > 1:
        parts.append(f"{s.iterations} iterations")
    if s.knots:
        parts.append(f"{s.knots} {s.spline} knots")
    return f"{LABELS.get(name, name)} ({', '.join(parts)})"


def rows(c: PlannerContext, name: str) -> dict:
    """{label: (SamplingSettings, SamplingHyper)}: planner ``name``'s rows, at D2C-MPC's
    budget first where ``budget_row`` asks for it (its own settings but ``samples``), then
    at its own settings."""
    own = own_settings(c, name)
    variants = [own]
    if own.budget_row and own.samples is not None and c.samples_matched:
        variants.insert(0, dataclasses.replace(own, samples=None))
    out = {}
    for o in variants:
        settings, hyper, _ = resolved(c, name, o)
        out.setdefault(label(name, settings, o), (settings, hyper))  # the same samples: one row
    return out


def sampling_episodes(name: str):
    """The planner kind's ``episodes(context)``: an episode of ``name``'s rule per row."""

    def episodes(c: PlannerContext) -> dict:
        return {
            row: bound_episode(
                mpc_sampling.sampling_mpc,
                c.system,
                c.plan_task,
                c.U0,
                steps=c.config.mpc.steps,
                settings=settings,
                hyper=hyper,
                replan_every=c.replan_every,
            )
            for row, (settings, hyper) in rows(c, name).items()
        }

    return episodes


def sampling_replans(name: str):
    """The planner kind's ``replans(context)``: ``name``'s replan per row for the wall-clock
    loop (``control.realtime``), its first plan the spline through the first plan U0."""

    def replans(c: PlannerContext) -> dict:
        U0 = c.U0.astype(c.task.x0.dtype)
        free = np.asarray(mpc_sampling.unbounded(c.plan_task))
        out = {}
        for row, (settings, hyper) in rows(c, name).items():
            replan = mpc_sampling.replanner(c.system, c.plan_task, settings, hyper)
            plan0 = mpc_sampling.first_spline_plan(U0, settings, hyper.sigma)
            shift = functools.partial(mpc_sampling.moved_on_host, s=settings, free=free)
            out[row] = realtime.RealTimePlanner(replan, plan0, shift)
        return out

    return replans


def sampling_steps(name: str):
    """Black-box control steps per control step of the row ``c.row`` (the first row where it
    names none): a replan's over the r steps it serves."""

    def steps(c: PlannerContext, result) -> float:
        found = rows(c, name)
        settings = found.get(getattr(c, "row", ""), next(iter(found.values())))[0]
        return mpc_sampling.black_box_steps(settings, c.config.mpc.horizon) / c.replan_every

    return steps
