"""A receding-horizon pass after an offline solve (``solver.receding_pass`` = H > 0).

iLQR over the whole horizon stops in the nearest local minimum of its start; replanning
over a shorter horizon from every state reached often escapes it (on ``cartpole_mpc``'s
swing-up, the offline optimum from zero controls juggles the pole at 2937 while D2C-MPC
over 2 s swings it up, docs/mpc.md). The pass runs that closed loop on the model itself,
without noise: D2C-MPC (:func:`mjx_surrogate.control.mpc.receding_horizon`) over H steps,
plans ending at the task's end (``Task.deadline``), at most 5 iterations per replan, the
first plan the solve's own first H controls; then D2C over the whole horizon from the
closed loop's T controls. The cheaper of that solve and the first is kept, by the
solver's cost.

The black-box steps are counted in the pass's record, whereas the run's
``simulated_steps`` are the kept solve's alone: ``first_steps``, the first solve's;
``closed_loop_steps``, the replans' (as :func:`mjx_surrogate.control.mpc.black_box_steps`
counts them) and the model's own T steps as the plant; ``refined_steps``, the second
solve's.
"""

from __future__ import annotations

import contextlib
import math
import time

import jax
import numpy as np

from mjx_surrogate import progress as progress_lib
from mjx_surrogate.control import chunked, mpc
from mjx_surrogate.control.effort import simulation_metrics
from mjx_surrogate.control.ilqr import ILQRParams
from mjx_surrogate.identification import sysid as sid
from mjx_surrogate.progress import NO_PROGRESS, ProgressMeter
from mjx_surrogate.systems.black_box import BlackBox
from mjx_surrogate.tasks import Task
from mjx_surrogate.timing import Timed

MAX_ITER_PER_REPLAN = 5  # D2C-MPC's default


def receding_pass(
    system: BlackBox,
    task: Task,
    timed: Timed,
    U0: jax.Array,
    key: jax.Array,
    params: ILQRParams,
    sysid: sid.SysIdParams,
    horizon: int,
    progress: ProgressMeter = NO_PROGRESS,
) -> tuple[Timed, jax.Array, dict | None]:
    """(the solve to keep, its start U0 [T, nu], the pass's record) after the solve
    ``timed`` from U0; with ``horizon`` 0, ``timed`` and U0 unchanged and no record. With
    ``progress`` on, the closed loop shows its control steps where ``progress`` shows a bar,
    and a stop request (SIGINT, SIGTERM) ends the pass at the next control step, keeping
    the first solve (``kept`` says so)."""
    if horizon <= 0:
        return timed, U0, None
    T = task.T
    H = min(horizon, T)
    U = timed.out.U
    t0 = time.perf_counter()
    replan_params = params.replace(max_iter=min(params.max_iter, MAX_ITER_PER_REPLAN))
    on = int(np.asarray(progress.meter_id)) >= 0
    bar = progress_lib.meter("receding pass", T, progress_lib.displays(progress), leave=False)
    with bar if on else contextlib.nullcontext(NO_PROGRESS) as pm:
        loop = mpc.receding_horizon(
            system,
            task.replace(T=H, deadline=T),
            U[:H],
            key=jax.random.fold_in(key, 3),
            steps=T,
            params=replan_params,
            sysid=sysid,
            progress=pm,
        )
    loop_s = time.perf_counter() - t0
    if progress_lib.stop_polled(progress):
        return timed, U0, {"horizon": H, "wall_s": loop_s, "kept": "the first solve: stopped during the pass"}
    refined = chunked.solve(system, task, loop.U, key, params, sysid, "d2c", progress)
    first, second = float(timed.out.cost), float(refined.out.cost)
    better = math.isfinite(second) and second <= first
    record = {
        "horizon": H,
        "closed_loop_cost": float(loop.cost),
        "iterations_per_replan": float(np.mean(loop.iterations)),
        "wall_s": loop_s,
        "closed_loop_steps": int(mpc.black_box_steps(loop, H, replan_params.n_alphas, sysid).sum()) + T,
        "first_cost": first,
        "first_steps": simulation_metrics(timed.out, T, params.n_alphas, sysid)["simulated_steps"],
        "refined_cost": second,
        "refined_iterations": int(refined.out.iterations),
        "refined_steps": simulation_metrics(refined.out, T, params.n_alphas, sysid)["simulated_steps"],
        "kept": "the refined solve" if better else "the first solve",
    }
    return (refined, loop.U, record) if better else (timed, U0, record)
