"""Receding-horizon planners by name: what ``mpc.controllers`` selects (docs/mpc.md).

A planner kind (:class:`PlannerKind`) turns the study's context (:class:`PlannerContext`:
the system, the offline task and its horizon-H copy, the offline optimum, the first plan,
the solver's settings) into its episodes, ``{label: episode(*, plant, key, process_noise,
progress) -> MPCResult}`` (keyword-only), one per planner it stands for (the surrogates'
kind: one per fitted model),
and counts its black-box steps per control step. Every episode runs the same loop,
:func:`mjx_surrogate.control.episode.episode`. Built in, in the order a study runs them:
``d2c``, ``oracle``, ``tvlqr``, ``surrogates``, ``predictive_sampling``, ``mppi``, ``cem``
(the sampling ones: :mod:`~.sampling_planners`), ``d2c_sampling`` (:mod:`~.mpc_hybrid`,
not among the default ``mpc.controllers``); a new planner is one function plus
:func:`register_planner`, and may bring settings (``--mpc.<name>.<field>``).
"""

from __future__ import annotations

from typing import Any, Callable, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from mjx_surrogate.control import mpc, mpc_hybrid, mpc_online, mpc_reuse, realtime, sampling_planners
from mjx_surrogate.control.episode import bound_episode, first_plan
from mjx_surrogate.control.ilqr import ILQRParams
from mjx_surrogate.control.sampling_rules import get_rule
from mjx_surrogate.errors import registered
from mjx_surrogate.identification.sysid import SysIdParams
from mjx_surrogate.surrogates.mlp import MLPModel
from mjx_surrogate.surrogates.registry import mlp_spec
from mjx_surrogate.surrogates.sindy import SindyModel
from mjx_surrogate.tasks import Task


class PlannerContext(NamedTuple):
    """What a planner is built from: the resolved config (its ``mpc`` section), the system
    planned on, the offline ``task`` and ``plan_task`` (its horizon-H copy), the offline
    ``optimum`` (``X_star`` [T+1, nx], ``U_star`` [T, nu], ``K_star`` [T, nu, nx]), the first
    plan U0 [H, nu], the replans' solver settings, the sampling planners' samples per replan,
    and ``fit() -> ({label: surrogate model}, training transitions)`` (fitted once);
    ``row``: the label whose black-box steps are asked (a kind with several rows)."""

    config: Any
    system: Any
    task: Task
    plan_task: Task
    optimum: dict
    U0: jax.Array
    params: ILQRParams
    sysid: SysIdParams
    samples: int
    fit: Callable[[], tuple[dict, Any]]
    replan_every: int = 1
    samples_matched: bool = False  # ``samples`` is D2C-MPC's budget (split over iterations)
    planner_settings: dict = {}  # name -> the run's values of that planner's own settings
    row: str = ""  # set by the study when it counts one row's black-box steps


Episode = Callable[..., mpc.MPCResult]  # (*, plant, key, process_noise, progress) -> MPCResult


class PlannerKind(NamedTuple):
    """``episodes(context) -> {label: Episode}``; ``black_box_steps(context, result)``:
    black-box control steps per control step of one condition's episodes [E, ...] (the
    plant's own step not counted), None where not counted; ``iterative``: it reports
    iterations per replan; ``replans(context) -> {label: RealTimePlanner}``: the same
    planners (labels as ``episodes``') for the wall-clock loop, or None."""

    episodes: Callable[[PlannerContext], dict[str, Episode]]
    black_box_steps: Callable[[PlannerContext, mpc.MPCResult], float | None]
    iterative: bool = False
    description: str = ""
    settings: Any = None  # its own settings' defaults (``--mpc.<name>.<field>``), or None
    # replans(context) -> {label: realtime.RealTimePlanner}, for ``mpc.realtime``; None: the
    # planner does not replan from the measured state alone (TVLQR, online refits)
    replans: Callable[[PlannerContext], dict[str, realtime.RealTimePlanner]] | None = None


PLANNERS: dict[str, PlannerKind] = {}


def register_planner(name: str, kind: PlannerKind) -> None:
    """Add ``kind`` under ``name`` (then valid in ``mpc.controllers``)."""
    PLANNERS[name] = kind


def get_planner(name: str, field: str = "mpc.controllers") -> PlannerKind:
    return registered(PLANNERS, name, field, "controller")


def _carried(c: PlannerContext, name: str) -> mpc_reuse.D2CPlannerSettings | None:
    """D2C-MPC's own settings where it carries its models across replans (planner ``name``
    "d2c" with ``reuse_tol`` > 0), else None."""
    own = c.planner_settings.get("d2c", mpc_reuse.D2CPlannerSettings())
    return own if name == "d2c" and own.reuse_tol > 0 else None


def _replanning(name: str):
    """D2C-MPC (``name`` "d2c") or an oracle's MPC on the black box."""

    def episodes(c: PlannerContext) -> dict[str, Episode]:
        method = "d2c" if name == "d2c" else c.config.experiment.oracle
        own = _carried(c, name)
        if own is not None:
            fn, extra = mpc_reuse.carried_receding_horizon, {"settings": own}
        else:
            fn, extra = mpc.receding_horizon, {"controller": method}
        one = bound_episode(
            fn,
            c.system,
            c.plan_task,
            c.U0,
            steps=c.config.mpc.steps,
            params=c.params,
            sysid=c.sysid,
            replan_every=c.replan_every,
            **extra,
        )
        return {"D2C-MPC" if name == "d2c" else f"oracle MPC ({method})": one}

    return episodes


def _replanning_replans(name: str):
    """D2C-MPC's or the oracle's replan for the wall-clock loop."""

    def replans(c: PlannerContext) -> dict:
        method = "d2c" if name == "d2c" else c.config.experiment.oracle
        own = _carried(c, name)
        if own is not None:
            replan = mpc_reuse.reuse_replan(c.system, c.plan_task, c.params, c.sysid, own)
            plan0 = mpc_reuse.first_carried_plan(c.U0, c.task.x0, own.reuse_max)
        else:
            replan = mpc.d2c_replan(c.system, c.plan_task, c.params, c.sysid, method)
            plan0 = first_plan(c.U0, c.task.x0)
        planner = realtime.RealTimePlanner(replan, plan0, realtime.moved_on)
        return {"D2C-MPC" if name == "d2c" else f"oracle MPC ({method})": planner}

    return replans


def _surrogate_replans(c: PlannerContext) -> dict:
    """MPC on each fitted surrogate for the wall-clock loop (not the refitted ones: they
    learn from the plant's steps between replans)."""
    models, _ = c.fit()
    plan0 = first_plan(c.U0, c.task.x0)

    def on_model(model):
        replan = mpc.surrogate_replanner(model, c.plan_task, c.params)
        return realtime.RealTimePlanner(replan, plan0, realtime.moved_on)

    return {f"{label} MPC": on_model(model) for label, model in models.items()}


def _d2c_steps(c: PlannerContext, result: mpc.MPCResult) -> float:
    """The median over episodes of each episode's mean steps per control step (a replan's
    over the control steps it serves)."""
    m = c.config.mpc
    per_episode = [
        mpc.black_box_steps(
            jax.tree.map(lambda a: a[e], result), m.horizon, c.params.n_alphas, c.sysid
        ).mean()
        / c.replan_every
        for e in range(m.n_episodes)
    ]
    return float(np.median(per_episode))


def _tracking(c: PlannerContext) -> dict[str, Episode]:
    N = c.config.mpc.steps
    X, U, K = (jnp.asarray(c.optimum[k]) for k in ("X_star", "U_star", "K_star"))
    ref = (X[: N + 1], U[:N], K[:N])

    def one(*, plant, key, process_noise, progress):
        return mpc.tracking(c.task, *ref, plant=plant, key=key, process_noise=process_noise)

    return {"TVLQR tracking": one}


def _surrogates(c: PlannerContext) -> dict[str, Episode]:
    """MPC on each fitted surrogate, and where ``mpc.refit_weight`` > 0 the same refitted
    online (SINDy; MLPs with ``mpc.refit_updates`` > 0)."""
    m, N, params = c.config.mpc, c.config.mpc.steps, c.params
    models, train = c.fit()

    common = dict(steps=N, params=params, replan_every=c.replan_every)

    def on_model(model):
        return bound_episode(mpc.surrogate_mpc, model, c.plan_task, c.U0, **common)

    def refitted_sindy(model):
        return bound_episode(
            mpc_online.refitted_sindy_mpc, model, train, c.plan_task, c.U0, weight=m.refit_weight, **common
        )

    def refitted_mlp(model, spec):
        return bound_episode(
            mpc_online.refitted_mlp_mpc,
            model,
            train,
            c.plan_task,
            c.U0,
            spec=spec,
            updates=m.refit_updates,
            weight=m.refit_weight,
            **common,
        )

    out = {f"{label} MPC": on_model(model) for label, model in models.items()}
    for label, model in models.items():
        if m.refit_weight > 0 and isinstance(model, SindyModel):
            out[f"{label} MPC refitted online"] = refitted_sindy(model)
        elif m.refit_weight > 0 and m.refit_updates > 0 and isinstance(model, MLPModel):
            out[f"{label} MPC refitted online"] = refitted_mlp(model, mlp_spec(c.config))
    return out


for _name, _kind in {
    "d2c": PlannerKind(
        _replanning("d2c"),
        _d2c_steps,
        True,
        "iLQR on LTV models identified at every replan (carried over where they still predict: reuse_tol)",
        mpc_reuse.D2CPlannerSettings(),
        replans=_replanning_replans("d2c"),
    ),
    "oracle": PlannerKind(
        _replanning("oracle"),
        lambda c, r: None,
        True,
        "iLQR on the oracle's Jacobians (experiment.oracle)",
        replans=_replanning_replans("oracle"),
    ),
    "tvlqr": PlannerKind(_tracking, lambda c, r: 0.0, False, "TVLQR tracking of the offline optimum"),
    "surrogates": PlannerKind(
        _surrogates, lambda c, r: 0.0, True, "iLQR on each global surrogate", replans=_surrogate_replans
    ),
    **{
        name: PlannerKind(
            sampling_planners.sampling_episodes(name),
            sampling_planners.sampling_steps(name),
            False,
            get_rule(name).description,
            sampling_planners.SETTINGS[name],
            sampling_planners.sampling_replans(name),
        )
        for name in ("predictive_sampling", "mppi", "cem")
    },
    "d2c_sampling": PlannerKind(
        mpc_hybrid.episodes,
        lambda c, result: _d2c_steps(c, result) + mpc_hybrid.proposal_steps(c),
        True,
        "D2C-MPC from the best of its warm start and S - 1 sampled proposals (iLQS)",
        mpc_hybrid.HybridSettings(),
        mpc_hybrid.replans,
    ),
}.items():
    register_planner(_name, _kind)
