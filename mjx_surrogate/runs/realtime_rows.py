"""The `mpc` kind's planners in real time (``mpc.realtime``): each condition's episodes of
every planner that replans from the measured state (``PlannerKind.replans``: D2C-MPC, the
oracle's MPC, MPC on each surrogate, the sampling planners, the hybrid) again, one after
another, in the wall-clock loop of ``mjx_surrogate.control.realtime`` (the plant at its
control period, the planner in a thread of its own, plans applied by their time stamps),
with the synchronous batch's keys: where every replan ends within a tick, the same closed
loops. A row per planner and condition, "<planner> in real time" (:func:`label`), beside
the synchronous one.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from mjx_surrogate import progress
from mjx_surrogate.control import realtime
from mjx_surrogate.runs import pipeline
from mjx_surrogate.tasks import trajectory_cost

SUFFIX = " in real time"
LABEL = "D2C-MPC" + SUFFIX


def label(planner: str) -> str:
    """The real-time row's label of the planner labelled ``planner``."""
    return planner + SUFFIX


def plant_step(plant):
    """The plant's (x, u) -> x in NumPy: native MuJoCo for a MuJoCo system, else its step."""
    if plant.mj_model is not None:
        return realtime.native_plant(plant.mj_model, plant.substeps)
    step = jax.jit(plant.step)
    return lambda x, u: np.asarray(step(jnp.asarray(x), jnp.asarray(u)), np.float64)


def condition(
    res, planner: realtime.RealTimePlanner, name: str, plant, noise: float, keys, every: int = 1
) -> tuple[dict, np.ndarray, np.ndarray]:
    """(row, X [E, N+1, nx], U [E, N, nu]) of one condition's episodes of ``planner``
    (labelled ``name``) in real time, replanning at most every ``every`` ticks."""
    cfg, system, task = res
    m = cfg.mpc
    replan = jax.jit(planner.replan)
    step = plant_step(plant)
    limits = (np.asarray(task.u_min), np.asarray(task.u_max))
    runs = []
    desc = f"  {label(name)}, noise {noise:g}: episodes"
    with progress.steps(desc, len(keys), cfg.experiment.progress) as meter:
        for i, k in enumerate(keys):
            meter.advance(f"episode {i}, {m.steps} ticks of {float(system.dt):g} s")
            runs.append(
                realtime.run(
                    replan,
                    step,
                    np.asarray(task.x0),
                    planner.plan0,
                    dt=float(system.dt),
                    steps=m.steps,
                    key=k,
                    limits=limits,
                    process_noise=noise,
                    speed=m.realtime_speed,
                    stop=progress.stop_requested,
                    shift=planner.shift,
                    replan_every=every,
                )  # fmt: skip
            )
    if progress.stop_requested():  # seen within a tick
        raise progress.Stopped("during the real-time episodes")
    X, U = np.stack([r.X for r in runs]), np.stack([r.U for r in runs])
    cost = jax.jit(trajectory_cost)
    costs = [float(cost(task, jnp.asarray(x), jnp.asarray(u))) for x, u in zip(X, U)]
    lag = np.concatenate([realtime.lateness(r.stamps, every) for r in runs])
    replan_s = float(np.median(np.concatenate([r.replan_s for r in runs])))
    row = {
        "controller": label(name),
        **pipeline.episode_outcomes(task, X, costs, cfg.task.goal_tolerance, float(system.dt)),
        "black_box_steps_per_control_step": None,
        "iterations_per_replan": None,
        "compute_per_step_s": replan_s / every,  # a replan's median wall time over its ticks
        "real_time_factor": every * float(system.dt) / replan_s,
        "replan_s_median": replan_s,
        "plans_late_ticks_median": float(np.median(lag)),
        "plans_late_ticks_max": int(lag.max()),
        "plant_late_ticks": int(sum(r.late_ticks for r in runs)),
        "realtime_speed": m.realtime_speed,
    }
    return row, X, U
