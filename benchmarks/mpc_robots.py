"""Robot tasks in closed loop: the tasks of benchmarks/robots.py (models we did not write,
downloaded at run time; default: the menagerie UR5e's reach) under D2C-MPC, with the plans
ending at the task's end and H steps ahead (``mpc.horizon_end`` "task" and "receding"), on
the model and on a heavier plant, with and without process noise. What a user who ran the
task offline runs next:

    python -m experiments.run <the task's config> --experiment.kind mpc \\
        --mpc.horizon 25 --mpc.steps 50

Per task, mode, plant and noise level: the closed-loop cost (median over the episodes), the
share of episodes that reached the goal (the task's goal test), black-box steps and
milliseconds per control step (compile apart) and the real-time factor. A point goal's
terminal weight is set to ``--final-weight``; a hold task has none.

    python benchmarks/mpc_robots.py [--tasks ur5e "walker (hold)"] [--modes task receding]
        [--episodes 2] [--final-weight 1000] [--max-iter 5] [--every 1] [--n-alphas A]
        [--replan-hz HZ] [--first-plan reference] [--scheme forward_difference] [--floor]
        [--reuse-tol 0.02] [--reuse-max 4] [--realtime] [--out DIR]

``--reuse-tol`` > 0 carries D2C-MPC's models from one replan to the next where they still
predict (``--mpc.d2c.reuse_tol``, ``mjx_surrogate.control.mpc_reuse``).

For a task with point goals the table adds the study's ``point_error_median``: the goal
points' distance from their targets (m; a moving target where it is at that step), averaged
over each episode's second half, the median over episodes: how closely the loop follows.

``--floor`` adds, per task and noise level, what the goal test can say under that noise
(``benchmarks/noise_floor.py``): how often the last noise draw alone fails it, and for a
hold task how often the LQR at the goal passes it.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import tempfile

_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, _ROOT)


# Control periods as the tasks' own suites run these models (the hold tasks otherwise step
# at the model's time step): dm_control's walker task (control_timestep 0.025 s) and
# gymnasium's Hopper (frame_skip 4 of 0.002 s).
CONTROL_DT = {"walker (hold)": 0.025, "hopper (hold)": 0.008}


def mpc_config(task: str, mode: str, args):
    """The robots benchmark's task ``task`` as an MPC study in ``mode``, or None."""
    from benchmarks.robots import task_config
    from mjx_surrogate.runs.config import MPCConfig, MPCSysIdConfig

    cfg = task_config(task)
    if cfg is None:
        return None
    goals = tuple(dataclasses.replace(g, final_weight=args.final_weight) for g in cfg.task.goals)
    if task in CONTROL_DT:
        cfg = dataclasses.replace(cfg, system=dataclasses.replace(cfg.system, control_dt=CONTROL_DT[task]))
    if args.scheme is not None:
        cfg = dataclasses.replace(cfg, sysid=dataclasses.replace(cfg.sysid, scheme=args.scheme))
    if args.reuse_tol > 0:
        carried = {"reuse_tol": args.reuse_tol, "reuse_max": args.reuse_max}
        cfg = dataclasses.replace(cfg, extensions={**cfg.extensions, "mpc.d2c": carried})
    return dataclasses.replace(
        cfg,
        task=dataclasses.replace(cfg.task, goals=goals),
        experiment=dataclasses.replace(
            cfg.experiment,
            kind="mpc",
            exact_oracle="oracle" in args.controllers,
            oracle="finite_difference",
            video=False,
            out_dir=args.out,
        ),
        mpc=MPCConfig(
            controllers=tuple(args.controllers),
            horizon=args.horizon,
            steps=args.steps or cfg.task.T or 50,
            horizon_end=mode,
            process_noise=tuple(args.noise),
            plants=tuple(args.plants),
            n_episodes=args.episodes,
            max_iter=args.max_iter,
            sysid=MPCSysIdConfig(every=args.every),
            n_alphas=args.n_alphas,
            replan_hz=args.replan_hz,
            first_plan=args.first_plan,
            realtime=args.realtime,
        ),
    )


def _g(v) -> str:
    return "-" if v is None else f"{v:.4g}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument(
        "--tasks",
        nargs="*",
        default=["ur5e servos (reach)"],
        help="substrings of benchmarks/robots.py's task names",
    )
    ap.add_argument(
        "--controllers", nargs="*", default=["d2c"], help="mpc.controllers (oracle: finite differences)"
    )
    ap.add_argument("--modes", nargs="*", default=["task", "receding"], help="mpc.horizon_end values")
    ap.add_argument("--horizon", type=int, default=25)
    ap.add_argument("--steps", type=int, default=None, help="episode length (default: the task's T, or 50)")
    ap.add_argument("--episodes", type=int, default=2)
    ap.add_argument("--max-iter", type=int, default=5, help="mpc.max_iter: iLQR iterations per replan")
    ap.add_argument("--every", type=int, default=1, help="mpc.sysid.every: identify every k-th step")
    ap.add_argument(
        "--scheme", default=None, help="sysid.scheme: the identification scheme (default: the solver's)"
    )
    ap.add_argument("--n-alphas", type=int, default=None, help="mpc.n_alphas (default: the solver's)")
    ap.add_argument("--replan-hz", type=float, default=None, help="mpc.replan_hz (default: every step)")
    ap.add_argument(
        "--first-plan", default="optimum", help="mpc.first_plan: every planner's first warm start"
    )
    ap.add_argument("--noise", type=float, nargs="*", default=[0.0, 0.01])
    ap.add_argument("--plants", nargs="*", default=["model", "mass=1.2"])
    ap.add_argument("--final-weight", type=float, default=1000.0, help="the goal's terminal weight")
    ap.add_argument(
        "--floor",
        action="store_true",
        help="also each noisy condition's noise floor (benchmarks/noise_floor.py)",
    )
    ap.add_argument(
        "--realtime", action="store_true", help="mpc.realtime: also each episode in the wall-clock loop"
    )
    ap.add_argument("--reuse-tol", type=float, default=0.0, help="mpc.d2c.reuse_tol (0: off)")
    ap.add_argument("--reuse-max", type=int, default=4, help="mpc.d2c.reuse_max")
    ap.add_argument("--out", default=os.path.join(tempfile.gettempdir(), "mpc_robots"))
    args = ap.parse_args()
    from benchmarks.noise_floor import floor
    from benchmarks.robots import TASKS
    from experiments.run import run
    from mjx_surrogate.runtime import configure_runtime

    configure_runtime(x64=True)
    results, floors = [], []
    for task in [n for n in TASKS if any(t in n for t in args.tasks)]:
        for mode in args.modes:
            cfg = mpc_config(task, mode, args)
            if cfg is None:
                print(f"{task}: model not reachable, skipped", file=sys.stderr)
                continue
            name = f"mpc_{mode}_it{args.max_iter}_every{args.every}_hz{args.replan_hz}_r{args.reuse_tol:g}"
            folder = run(cfg, name=name)
            with open(os.path.join(folder, "metrics.json")) as f:
                metrics = json.load(f)
            for r in metrics["mpc_rows"]:
                results.append({"task": task, "mode": mode, "offline_cost": metrics["d2c"]["cost"]} | r)
            if args.floor:
                floors += [floor(folder, w, 4000, 0) | {"task": task} for w in args.noise if w > 0]
    print(
        "| task | controller | horizon end | plant | noise | cost (median) | offline optimum | goal reached "
        "| black-box steps / step | ms / step | real-time factor | point error, 2nd half (m) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in results:
        print(
            f"| {r['task']} | {r['controller']} | {r['mode']} | {r['plant']} | {r['process_noise']:g} | "
            f"{_g(r['cost_median'])} | "
            f"{_g(r['offline_cost'])} | "
            f"{100 * r['goal_reached']:.0f} % | {_g(r['black_box_steps_per_control_step'])} | "
            f"{1e3 * r['compute_per_step_s']:.0f} | {r['real_time_factor']:.2f} | "
            f"{_g(r.get('point_error_median'))} |"
        )

    if floors:
        print("\nNoise floor of the goal test (model plant; benchmarks/noise_floor.py):\n")
        print(
            "| task | noise | last draw alone fails | LQR at the goal: passes | LQR cost (median, p10-p90) |"
        )
        print("|---|---|---|---|---|")
        for f in floors:
            lqr = ("-", "-")
            if "lqr_pass" in f:
                lo, hi = f["lqr_cost_p10_p90"]
                lqr = (f"{100 * f['lqr_pass']:.0f} %", f"{f['lqr_cost_median']:.3g} ({lo:.3g}-{hi:.3g})")
            print(
                f"| {f['task']} | {f['noise']:g} | {100 * f['last_draw_fails']:.1f} % | {lqr[0]} | {lqr[1]} |"
            )


if __name__ == "__main__":
    main()
