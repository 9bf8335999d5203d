"""D2C-MPC with sampling proposals (planner ``d2c_sampling``), as MuJoCo MPC's iLQS puts
sampling before iLQG: at every replan, S - 1 smooth perturbations of the warm start's
controls (drawn at spline knots, ``mpc_sampling``'s splines) are rolled out on the black
box beside the warm start itself; D2C-MPC's replan (:func:`mpc.ilqr_replan`) then starts
from the cheapest. Where the warm start wins, the replan is D2C-MPC's own (its policy kept);
where a draw wins, the replan starts from that draw's controls alone.

What it is for: a start where every local model says the controls do not change the cost
(a pendulum hanging at rest under zero controls: the cost's gradient vanishes there, and
D2C-MPC never moves) or a local minimum the draws see past. It costs S x H black-box
steps per replan on top of D2C-MPC's.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any, Literal, Optional

import jax
import jax.numpy as jnp

from mjx_surrogate.control import mpc, realtime
from mjx_surrogate.control.d2c import problem
from mjx_surrogate.control.episode import Plan, bound_episode, first_plan
from mjx_surrogate.control.ilqr import ILQRParams
from mjx_surrogate.control.mpc_sampling import reading
from mjx_surrogate.control.sampling_planners import spread_scale
from mjx_surrogate.errors import ConfigError
from mjx_surrogate.identification import sysid as sid
from mjx_surrogate.progress import NO_PROGRESS, ProgressMeter
from mjx_surrogate.systems.black_box import BlackBox
from mjx_surrogate.tasks import Task, at_step, trajectory_cost
from mjx_surrogate.trajectory import open_loop


@dataclasses.dataclass(frozen=True)
class HybridSettings:
    """The proposals' settings (``--mpc.d2c_sampling.<field>``): S ``samples`` per replan
    (the warm start among them), their spread ``sigma`` (None: mpc.sampling_sigma) in
    ``sigma_units`` (as the sampling planners'), drawn at ``knots`` knots of ``spline``."""

    samples: int = 16
    sigma: Optional[float] = None
    sigma_units: Literal["range", "control"] = "range"
    knots: int = 4
    spline: Literal["zero", "linear", "cubic"] = "zero"

    def check(self) -> None:
        if self.samples < 2:
            raise ConfigError("samples", f"must be >= 2 (the warm start and one draw), got {self.samples}")
        if self.sigma is not None and self.sigma < 0:
            raise ConfigError("sigma", f"must be >= 0, or unset, got {self.sigma}")
        if self.knots < 0:
            raise ConfigError("knots", f"must be >= 0 (0: every step its own draw), got {self.knots}")


def proposals(key: jax.Array, U: jax.Array, n: int, knots: int, spline: str, sigma, lo, hi) -> jax.Array:
    """[n, H, nu]: U [H, nu] itself and n - 1 draws U + sigma W z, z ~ N(0, I) at ``knots``
    knots read through ``spline`` (W = I with knots 0), clipped to [lo, hi]."""
    H, nu = U.shape
    z = jax.random.normal(key, (n - 1, knots or H, nu), U.dtype)
    W = reading(H, knots, spline)
    if W is not None:
        z = jnp.einsum("tk,skj->stj", jnp.asarray(W, U.dtype), z)
    return jnp.concatenate([U[None], jnp.clip(U + sigma * z, lo, hi)])


@functools.partial(
    jax.jit, static_argnames=("system", "steps", "plant", "replan_every", "n_samples", "knots", "spline")
)
def hybrid_mpc(
    system: BlackBox,
    task: Task,
    U0: jax.Array,
    *,
    key: jax.Array,
    steps: int,
    params: ILQRParams,
    sysid: sid.SysIdParams,
    sigma: jax.Array,
    n_samples: int = 16,
    knots: int = 4,
    spline: str = "zero",
    process_noise: float | jax.Array = 0.0,
    plant: BlackBox | None = None,
    progress: ProgressMeter = NO_PROGRESS,
    replan_every: int = 1,
) -> mpc.MPCResult:
    """One episode of D2C-MPC with ``n_samples`` sampling proposals per replan (module
    docstring); the rest as :func:`mpc.receding_horizon`."""
    plant_step = (plant if plant is not None else system).step
    return mpc.ilqr_episode(
        replanner(system, task, params, sysid, sigma, n_samples, knots, spline),
        plant_step,
        task,
        U0,
        key=key,
        steps=steps,
        process_noise=process_noise,
        progress=progress,
        replan_every=replan_every,
    )


def replanner(
    system: BlackBox,
    task: Task,
    params: ILQRParams,
    sysid: sid.SysIdParams,
    sigma: jax.Array,
    n_samples: int,
    knots: int,
    spline: str,
):
    """The hybrid's ``replan(x, plan, key, n) -> (Plan, info)`` (module docstring), as
    :func:`hybrid_mpc`'s episode and the wall-clock loop call it."""
    lo, hi = task.u_min, task.u_max

    def replan(x, plan, k, n):
        k_draw, k_solve = jax.random.split(k)
        planned = at_step(task, n)
        U = proposals(k_draw, plan.U, n_samples, knots, spline, sigma, lo, hi)
        J = jax.vmap(lambda Ui: trajectory_cost(planned, *open_loop(system.step, x, Ui, lo, hi)))(U)
        best = jnp.argmin(J)
        start = Plan(U[best], plan.X, jnp.where(best > 0, 0.0, plan.K))  # a draw: its controls alone
        prob = problem(system, planned.replace(x0=x), sysid, "d2c")._replace(linearize_fine=None)
        return mpc.ilqr_replan(prob, start, params, k_solve)

    return replan


def _settings(c: Any) -> tuple[HybridSettings, jax.Array]:
    """(the hybrid's own settings, its spread [nu] in control units) in context ``c``."""
    own = c.planner_settings.get("d2c_sampling", HybridSettings())
    scale = spread_scale(c.plan_task.u_min, c.plan_task.u_max, own.sigma_units)
    sigma = c.config.mpc.sampling_sigma if own.sigma is None else own.sigma
    return own, jnp.asarray(sigma * scale, c.task.x0.dtype)


def _label(own: HybridSettings) -> str:
    return f"D2C-MPC + sampling (S={own.samples})"


def episodes(c: Any) -> dict:
    """The planner kind's episodes (``c``: a ``planners.PlannerContext``)."""
    own, sigma = _settings(c)
    m = c.config.mpc
    one = bound_episode(
        hybrid_mpc,
        c.system,
        c.plan_task,
        c.U0,
        steps=m.steps,
        params=c.params,
        sysid=c.sysid,
        sigma=sigma,
        n_samples=own.samples,
        knots=own.knots,
        spline=own.spline,
        replan_every=c.replan_every,
    )

    return {_label(own): one}


def replans(c: Any) -> dict:
    """The planner kind's replans for the wall-clock loop (``control.realtime``)."""
    own, sigma = _settings(c)
    args = (c.params, c.sysid, sigma, own.samples, own.knots, own.spline)
    planner = realtime.RealTimePlanner(
        replanner(c.system, c.plan_task, *args), first_plan(c.U0, c.task.x0), realtime.moved_on
    )
    return {_label(own): planner}


def proposal_steps(c: Any) -> float:
    """The proposals' black-box steps per control step: S x H per replan, over the r
    control steps a replan serves (D2C-MPC's own are counted as for ``d2c``)."""
    own = c.planner_settings.get("d2c_sampling", HybridSettings())
    return own.samples * c.config.mpc.horizon / c.replan_every
