"""Experiment kind "mpc": receding-horizon control on the black box, every controller of
section ``mpc`` side by side (docs/mpc.md).

Stages: ``d2c``, the offline optimum on the task's T steps (TVLQR's reference, the centre
of the surrogates' data and every planner's first plan), then one per planner and
condition, ``mpc/<controller>/<tag>`` (a stop keeps the conditions finished before it):
episodes of ``mpc.steps`` control steps on each plant (``mpc.plants``) at each
process-noise level, ``mpc.n_episodes`` each (batched by ``vmap``, the same keys, hence the
same noise draws, for every controller). "surrogates" first fits every kind of
``surrogate.kinds`` on ``data.n_traj`` trajectories around the optimum at ``mpc.data_level``.
Per controller and condition: closed-loop cost on the plant, goal reached, black-box steps
per control step, compute per control step (compile apart, the batch's wall time over its
episode steps) and the real-time factor (control period / compute per step).
"""

from __future__ import annotations

import functools
import time
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from mjx_surrogate import progress
from mjx_surrogate.analysis.closed_loop import cause_text, closed_loop_verdict, table
from mjx_surrogate.analysis.evaluation import finite_or_none
from mjx_surrogate.control.planners import PLANNERS, PlannerContext, get_planner
from mjx_surrogate.identification import data
from mjx_surrogate.runs import pipeline, plots, realtime_rows
from mjx_surrogate.runs.extension_settings import settings_of
from mjx_surrogate.runs.resolution import Resolved, mpc_params, plant_builder, replan_every
from mjx_surrogate.runs.results import Run
from mjx_surrogate.surrogates import FitContext, fit_all
from mjx_surrogate.systems.plant import make_plant, parse_plant, plant_label, plant_slug
from mjx_surrogate.tasks import trajectory_cost

DEFAULT_SAMPLES = 64  # sampling MPCs' samples per replan when D2C-MPC did not run


def _controller(controller: str, context: PlannerContext, res, record, plants, key) -> list[dict]:
    """Every episode batch of one controller: a stage per planner, plant and noise level
    (``mpc/<controller>/<tag>``), so that a stop or a failure keeps the conditions finished
    before it and a resumed run reuses them. Returns their rows."""
    cfg, system, task = res
    m = cfg.mpc
    conditions = [(p, w) for p in plants for w in m.process_noise]
    rows = []
    with progress.steps(f"MPC {controller}", 1 + len(conditions), cfg.experiment.progress) as meter:
        meter.advance("fit the surrogates" if controller == "surrogates" else "set up")
        kind = get_planner(controller)
        planners = kind.episodes(context)
        in_real_time = kind.replans(context) if m.realtime and kind.replans is not None else {}
        meter.extend(len(conditions) * (len(planners) - 1))
        stems = _stems(list(planners))
        for label, one in planners.items():
            for pi, (name, plant) in enumerate(plants.items()):
                batch = jax.jit(  # the meter closed over by the vmap: one stop answer per batch
                    lambda keys, w, pm, plant=plant, one=one: jax.vmap(
                        lambda k: one(plant=plant, key=k, process_noise=w, progress=pm)
                    )(keys)
                )
                compiled = {}  # once per planner and plant, for every noise level
                for ni, noise in enumerate(m.process_noise):
                    meter.advance(f"{label}, plant {name}, noise {noise:g}")
                    ci = pi * len(m.process_noise) + ni
                    tag = f"mpc_{stems[label]}_{ci}"
                    error_here = pi == 0 and noise == min(m.process_noise)  # the one-step error's condition
                    episodes = _Episodes(controller, label, name, noise, ci, tag, error_here)

                    def compute(e=episodes, batch=batch):
                        return _condition(res, context, e, batch, compiled, key)

                    row, _ = record.stage(f"mpc/{controller}/{tag}", compute)
                    rows.append(row)
                    if label in in_real_time:
                        planner = in_real_time[label]
                        rows.append(_realtime(res, planner, context, record, plant, episodes, key))
    return rows


def _stems(labels: list[str]) -> dict[str, str]:
    """{label: its stages' and arrays' name stem}: the label before its settings, with the
    row's index appended where an earlier row of the planner has the same stem (a sampling
    planner's rows at D2C-MPC's budget and at its own samples)."""
    out, seen = {}, set()
    for i, label in enumerate(labels):
        stem = label.split(" (")[0].replace(" ", "_")
        out[label] = f"{stem}_{i}" if stem in seen else stem
        seen.add(stem)
    return out


def _realtime(res, planner, context: PlannerContext, record, plant, e: "_Episodes", key) -> dict:
    """The condition's episodes again in the wall-clock loop (``mpc.realtime``), with the
    batch's keys: a stage of their own (``mpc/<controller>/<tag>_rt``)."""
    keys = jax.random.split(jax.random.fold_in(key, e.index), res.config.mpc.n_episodes)

    def compute():
        every = context.replan_every
        row, X, U = realtime_rows.condition(res, planner, e.label, plant, e.noise, keys, every)
        tag = f"{e.tag}_rt"
        row |= {"plant": e.plant, "process_noise": e.noise, "arrays": {"X": f"{tag}_X", "U": f"{tag}_U"}}
        return row, {f"{tag}_X": X, f"{tag}_U": U}

    row, _ = record.stage(f"mpc/{e.controller}/{e.tag}_rt", compute)
    return row


class _Episodes(NamedTuple):
    """One condition of one planner: its controller kind and label, plant, noise level,
    condition index (its keys), array tag, and whether a surrogate's one-step error along
    its closed loop is measured here (the first plant, the least noise)."""

    controller: str
    label: str
    plant: str
    noise: float
    index: int
    tag: str
    one_step_error: bool


def _condition(res, context: PlannerContext, e: _Episodes, batch, compiled: dict, key) -> tuple[dict, dict]:
    """The row and arrays of one condition's ``mpc.n_episodes`` episodes, run as one batch
    (compiled once per planner and plant, the compile timed apart)."""
    cfg, _, task = res
    m = cfg.mpc
    keys = jax.random.split(jax.random.fold_in(key, e.index), m.n_episodes)
    w = jnp.asarray(e.noise, task.x0.dtype)
    compile_s = 0.0
    if "program" not in compiled:
        t0 = time.perf_counter()
        compiled["program"] = batch.lower(keys, w, progress.NO_PROGRESS).compile()
        compile_s = time.perf_counter() - t0
    desc = f"  {e.label}, noise {e.noise:g}: control steps"
    with progress.meter(desc, m.steps, cfg.experiment.progress, leave=False) as meter:
        t0 = time.perf_counter()
        r = jax.block_until_ready(compiled["program"](keys, w, meter))
        run_s = time.perf_counter() - t0
    if progress.stop_requested():  # the batch skipped its remaining steps: nothing to keep
        raise progress.Stopped(f"during {e.label}'s episodes")
    row, X, U = _row(res, e, r, run_s, context)
    row["compile_s"] = compile_s
    models = context.fit()[0] if e.controller == "surrogates" else {}
    model = models.get(e.label.removesuffix(" MPC"))  # not the refitted ones
    if model is not None and e.one_step_error:
        row["closed_loop_one_step_error"] = _one_step_error(model, X[0], U[0], context.optimum)
    row["arrays"] = {"X": f"{e.tag}_X", "U": f"{e.tag}_U"}
    return row, {f"{e.tag}_X": X, f"{e.tag}_U": U}


def _row(res, e: _Episodes, r, run_s: float, context: PlannerContext) -> tuple[dict, np.ndarray, np.ndarray]:
    cfg, system, task = res
    m = cfg.mpc
    kind = get_planner(e.controller)
    X, U = np.asarray(r.X), np.asarray(r.U)
    costs = np.asarray(r.cost, dtype=float)
    per_step = run_s / (m.n_episodes * m.steps)
    row = {
        "controller": e.label,
        "plant": e.plant,
        "process_noise": e.noise,
        **pipeline.episode_outcomes(task, X, costs, cfg.task.goal_tolerance, float(system.dt)),
        "black_box_steps_per_control_step": kind.black_box_steps(context._replace(row=e.label), r),
        "iterations_per_replan": float(np.mean(r.iterations)) if kind.iterative else None,
        "compute_per_step_s": per_step,
        "real_time_factor": float(system.dt) / per_step,
    }
    return row, X, U


def _one_step_error(model, X, U, optimum) -> float | None:
    """Median over t of |model.step(x_t, u_t) - x_{t+1}| along one closed loop X [N+1, nx],
    U [N, nu], relative to the RMS state of the offline optimum."""
    pred = np.asarray(jax.jit(jax.vmap(model.step))(jnp.asarray(X[:-1]), jnp.asarray(U)))
    err = np.linalg.norm(pred - X[1:], axis=-1)
    scale = float(np.sqrt(np.mean(np.sum(np.asarray(optimum["X_star"]) ** 2, axis=-1))))
    return finite_or_none(np.median(err) / scale)


def _plants(res, record) -> dict:
    """{label: plant} of ``mpc.plants``: the system itself for "model"; a changed MuJoCo
    model kept in the run folder (``plant_<slug>.mjb``) for replays; a function black box
    rebuilt with other parameters."""
    cfg, system, _ = res
    build = plant_builder(cfg, system)
    return {
        plant_label(parse_plant(p)): make_plant(system, p, record.folder.path, build) for p in cfg.mpc.plants
    }


def first_controls(first_plan: str, U_star: jax.Array, u_ref: jax.Array, H: int) -> jax.Array:
    """Every planner's first warm start [H, nu] (``mpc.first_plan``): the offline optimum
    U_star [T, nu] cut or extended by its last control to H steps, zeros, or u_ref [nu] at
    every step."""
    T = U_star.shape[0]
    if first_plan == "zeros":
        return jnp.zeros((H,) + U_star.shape[1:], U_star.dtype)
    if first_plan == "reference":
        return jnp.broadcast_to(jnp.asarray(u_ref, U_star.dtype), (H,) + U_star.shape[1:])
    return jnp.concatenate([U_star, jnp.repeat(U_star[-1:], max(0, H - T), axis=0)])[:H]


def run(res: Resolved, record: Run, key: jax.Array) -> str:
    cfg, system, task = res
    m, dc = cfg.mpc, cfg.data
    k_opt, k_data, k_mpc = jax.random.split(key, 3)
    record.add_arrays({"x0": task.x0})
    m_d2c, optimum = record.stage("d2c", pipeline.optimum_stage(res, k_opt))
    if m_d2c["cost"] is None:
        return "diverged"
    X_star, U_star = jnp.asarray(optimum["X_star"]), jnp.asarray(optimum["U_star"])
    H = m.horizon
    U0 = first_controls(m.first_plan, U_star, task.u_ref, H)
    plan_task = task.replace(T=H, deadline=task.T if m.horizon_end == "task" else None)
    record.set("mpc_horizon_end", {"mode": m.horizon_end, "why": horizon_end_text(m, task.T)})
    plants = _plants(res, record)
    record.set(
        "mpc_conditions",
        [{"plant": p, "process_noise": w} for p in plants for w in m.process_noise],
    )

    @functools.cache  # the models once: their MPCs, then their closed loops' one-step errors
    def fit():
        ds = data.sample(
            system, X_star, U_star, k_data, dc.n_traj, m.data_level, dc.x0_sigma, task.u_min, task.u_max
        )
        train, test = data.split(ds, jax.random.fold_in(k_data, 1), dc.test_fraction)
        train = data.transitions(train)
        fitted = fit_all(
            FitContext(cfg, system, task.T), train, data.transitions(test), jax.random.fold_in(k_data, 2)
        )
        return {label: jax.tree.map(np.asarray, f.model) for label, f in fitted.items()}, train

    rows = []
    params, sysid = mpc_params(cfg)
    every = replan_every(m, float(system.dt))
    record.set("mpc_replan", {"every_control_steps": every, "hz": 1.0 / (every * float(system.dt))})
    own = {n: settings_of(cfg, "mpc", n) for n, kind in PLANNERS.items() if kind.settings is not None}
    context = PlannerContext(
        cfg,
        system,
        task,
        plan_task,
        optimum,
        U0,
        params,
        sysid,
        m.samples or DEFAULT_SAMPLES,
        fit,
        every,
        planner_settings=own,
    )
    # the oracle follows experiment.exact_oracle (off for a user's MJCF: minutes of compile)
    chosen = [c for c in PLANNERS if c in m.controllers and (c != "oracle" or cfg.experiment.exact_oracle)]
    if "oracle" in m.controllers and "oracle" not in chosen:
        record.set("mpc_skipped", {"oracle": "experiment.exact_oracle is off"})
    for c in chosen:
        done = _controller(c, context, res, record, plants, k_mpc)
        rows += done
        if c == "d2c" and m.samples is None:  # the sampling MPCs get D2C-MPC's budget
            calls = np.median(
                [r["black_box_steps_per_control_step"] for r in done if r["controller"] == "D2C-MPC"]
            )
            context = context._replace(samples=max(2, int(round(calls * every / H))), samples_matched=True)
    record.set("mpc_rows", rows)
    N = m.steps  # the offline optimum's cost over an episode's steps: what "works" is judged on
    offline = float(trajectory_cost(task, X_star[: N + 1], U_star[:N])) if N <= task.T else None
    verdict = closed_loop_verdict(rows, finite_or_none(offline))
    record.set("mpc_verdict", verdict | {"cause": cause_text(rows)})
    _figures(record, res, rows, X_star)
    text = table(
        rows, float(system.dt), record.metrics["mpc_verdict"], plans_text(m, task.T, every, system.dt)
    )
    record.folder.write_text("mpc_table.md", text)
    if cfg.experiment.video and system.mj_model is not None:  # episode 0 of the hardest condition
        last = f"_{len(m.plants) * len(m.process_noise) - 1}_X"
        clips = {r["controller"]: r["arrays"]["X"] for r in rows if r["arrays"]["X"].endswith(last)}
        record.set("mpc_video_order", list(clips))
        record.video("mpc_episodes.mp4", list(clips.values()), float(system.dt), labels=list(clips))
    return m_d2c["status"]


def horizon_end_text(m, T: int) -> str:
    """Where the episodes' plans end (mpc.horizon_end, resolved), in one sentence."""
    if m.horizon_end == "task":
        return (
            f"every plan ends at the task's end (step {T}) or {m.horizon} steps ahead, whichever "
            "comes first: the terminal cost stays where the task puts it"
        )
    why = f"the episodes run {m.steps} steps, past the task's {T}" if m.steps > T else "as configured"
    return f"every plan ends {m.horizon} steps ahead, its terminal cost moving with it ({why})"


def plans_text(m, T: int, every: int, dt) -> str:
    """Where the plans end and, when not at every control step, how often they are made."""
    if every == 1:
        return horizon_end_text(m, T)
    return (
        f"{horizon_end_text(m, T)}; every planner replans every {every} control steps "
        f"({1.0 / (every * float(dt)):g} Hz), the plant stepping under its last plan in between"
    )


def _figures(record, res, rows, X_star) -> None:
    cfg, system, task = res
    m = cfg.mpc
    labels = list(dict.fromkeys(r["controller"] for r in rows))
    for p in dict.fromkeys(r["plant"] for r in rows):
        costs = {
            c: np.array(
                [
                    [np.inf if v is None else v for v in r["costs"]]
                    for r in rows
                    if r["controller"] == c and r["plant"] == p
                ]
            )
            for c in labels
        }
        record.figure(
            f"mpc_cost_vs_noise_{plant_slug(parse_plant(p))}.png",
            lambda costs=costs, p=p: plots.cost_vs_noise(
                np.asarray(m.process_noise),
                costs,
                f"{system.name}: MPC on the plant ({p})",
                xlabel="process noise std (state units)",
            ),
        )
    points = {
        c: [(r["black_box_steps_per_control_step"], r["cost_median"]) for r in rows if r["controller"] == c]
        for c in labels
    }
    record.figure(
        "mpc_cost_vs_calls.png",
        lambda: plots.cost_vs_calls(points, f"{system.name}: closed-loop cost against black-box calls"),
    )
    last = len(m.plants) * len(m.process_noise) - 1  # the last plant at the most noise
    paths = {
        r["controller"]: record.arrays[r["arrays"]["X"]][0]
        for r in rows
        if r["arrays"]["X"].endswith(f"_{last}_X")
    }
    t = np.arange(m.steps + 1) * system.dt
    coords = list(range(min(system.nq, 2)))
    record.figure(
        "mpc_trajectories.png",
        lambda: plots.predictions(
            t,
            np.asarray(X_star)[: m.steps + 1],
            paths,
            coords,
            list(system.state_labels),
            (list(system.angle_pairs) or [None])[0],
            f"{system.name}: closed loops, plant {plant_label(parse_plant(m.plants[-1]))}, "
            f"noise {m.process_noise[-1]:g}",
            reference_label="offline D2C optimum",
        ),
    )
