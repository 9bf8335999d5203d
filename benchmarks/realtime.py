"""D2C-MPC in the loop users run in real time (``mjx_surrogate.control.realtime``): the plant
(native MuJoCo, float64) steps on the wall clock at its control period while the planner
replans in a thread of its own; against the same planner in the synchronous episode, where
every replan ends before the plant moves (``mpc.receding_horizon``).

Per noise level and loop: the closed-loop cost (median over episodes), the goal test, how
late the plans were applied (ticks from a plan's measurement to the tick that used it:
median and largest), replans per tick, a replan's wall time (median), and the ticks on
which the plant itself fell behind. Every plan starts from the task's u_ref (no offline
solve); compile comes before the clock starts.

    python benchmarks/realtime.py [--tasks follow] [--preset gym_inverted_pendulum_mpc]
        [--horizon 10] [--max-iter 1] [--n-alphas 3] [--scheme forward_difference]
        [--mode task] [--episodes 4] [--noise 0 0.01] [--speed 1]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import tempfile
import time

_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, _ROOT)


def configs(args) -> list[tuple[str, object]]:
    """[(name, Config)] of the robots tasks matching ``--tasks`` and the ``--preset``."""
    from benchmarks.mpc_robots import mpc_config
    from benchmarks.robots import TASKS
    from experiments.run import load_config

    out = []
    for name in [n for n in TASKS if any(t in n for t in args.tasks)]:
        cfg = mpc_config(name, args.mode, args)
        if cfg is not None:
            out.append((name, cfg))
    if args.preset:
        cfg = load_config(args.preset)
        m = cfg.mpc
        fields = {"max_iter": args.max_iter, "n_alphas": args.n_alphas, "horizon": args.horizon}
        fields = {k: v for k, v in fields.items() if v is not None}
        scheme = args.mpc_scheme or m.sysid.scheme
        mpc = dataclasses.replace(m, sysid=dataclasses.replace(m.sysid, scheme=scheme), **fields)
        out.append((args.preset, dataclasses.replace(cfg, mpc=mpc)))
    return out


def measure(cfg, args) -> list[dict]:
    import jax
    import jax.numpy as jnp
    import numpy as np

    from mjx_surrogate.control import mpc, realtime
    from mjx_surrogate.control.episode import first_plan
    from mjx_surrogate.runs import pipeline
    from mjx_surrogate.runs.resolution import mpc_params, resolve
    from mjx_surrogate.tasks import trajectory_cost

    cfg, system, task = resolve(cfg)
    m = cfg.mpc
    params, sysid = mpc_params(cfg)
    H, steps, dt = m.horizon, m.steps, float(system.dt)
    plan_task = task.replace(T=H, deadline=task.T if m.horizon_end == "task" else None)
    U0 = jnp.broadcast_to(task.u_ref, (H,) + task.u_ref.shape)
    replan = jax.jit(mpc.d2c_replan(system, plan_task, params, sysid))
    episode = jax.jit(
        lambda key, w: mpc.receding_horizon(
            system, plan_task, U0, key=key, steps=steps, params=params, sysid=sysid, process_noise=w
        )
    )
    limits = (np.asarray(task.u_min), np.asarray(task.u_max))
    cost = jax.jit(trajectory_cost)
    rows = []
    for w in args.noise:
        keys = jax.random.split(jax.random.key(cfg.experiment.seed), args.episodes)
        jax.block_until_ready(episode(keys[0], w))  # compile apart
        loops = {"synchronous": [], "real time": []}
        for k in keys:
            t = time.perf_counter()
            r = jax.block_until_ready(episode(k, w))
            loops["synchronous"].append((np.asarray(r.X), np.asarray(r.U), time.perf_counter() - t, None))
            plant = realtime.native_plant(system.mj_model, system.substeps)
            rt = realtime.run(
                replan, plant, np.asarray(task.x0), first_plan(U0, task.x0), dt=dt, steps=steps,
                key=k, limits=limits, process_noise=w, speed=args.speed,
            )  # fmt: skip
            loops["real time"].append((rt.X, rt.U, rt.wall_s, rt))
        for loop, eps in loops.items():
            costs = [float(cost(task, jnp.asarray(X), jnp.asarray(U))) for X, U, _, _ in eps]
            goals = [
                pipeline.goal_test(task, jnp.asarray(X), cfg.task.goal_tolerance)["reached"]
                for X, _, _, _ in eps
            ]
            row = {"noise": w, "loop": loop, "cost": float(np.median(costs)), "reached": sum(goals)}
            row["episodes"] = len(eps)
            if loop == "synchronous":
                row["real_time_factor"] = steps * dt / float(np.median([e[2] for e in eps]))
            else:
                rts = [e[3] for e in eps]
                lag = np.concatenate([realtime.lateness(r.stamps) for r in rts])
                row |= {
                    "lag_median": float(np.median(lag)),
                    "lag_max": int(lag.max()),
                    "replans_per_tick": float(np.mean([len(r.replan_s) / steps for r in rts])),
                    "replan_ms": 1e3 * float(np.median(np.concatenate([r.replan_s for r in rts]))),
                    "late_ticks": int(sum(r.late_ticks for r in rts)),
                }
            rows.append(row)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument(
        "--tasks", nargs="*", default=["follow"], help="substrings of benchmarks/robots.py's tasks"
    )
    ap.add_argument("--preset", default=None, help="an mpc preset too, e.g. gym_inverted_pendulum_mpc")
    ap.add_argument("--mode", default="task", help="mpc.horizon_end of the robots tasks")
    ap.add_argument("--horizon", type=int, default=None, help="mpc.horizon (robots: 25)")
    ap.add_argument("--steps", type=int, default=None)
    ap.add_argument("--episodes", type=int, default=4)
    ap.add_argument("--max-iter", type=int, default=1)
    ap.add_argument("--every", type=int, default=1)
    ap.add_argument("--n-alphas", type=int, default=None)
    ap.add_argument("--scheme", default=None, help="sysid.scheme of the robots tasks")
    ap.add_argument("--mpc-scheme", default=None, help="mpc.sysid.scheme of the preset")
    ap.add_argument("--noise", type=float, nargs="*", default=[0.0, 0.01])
    ap.add_argument("--speed", type=float, default=1.0, help="the plant's clock: 1 is real time")
    args = ap.parse_args()
    # the rest of what benchmarks/mpc_robots.py's mpc_config reads
    defaults = {"controllers": ["d2c"], "plants": ["model"], "final_weight": 1000.0, "replan_hz": None}
    defaults |= {"first_plan": "reference", "out": os.path.join(tempfile.gettempdir(), "realtime")}
    for k, v in defaults.items():
        setattr(args, k, v)
    horizon = args.horizon
    from mjx_surrogate.runtime import configure_runtime

    configure_runtime(x64=True)
    for name, cfg in configs(args):
        if cfg.mpc.horizon is None and horizon is None:  # a robots task: mpc_robots' default
            cfg = dataclasses.replace(cfg, mpc=dataclasses.replace(cfg.mpc, horizon=25))
        print(f"\n{name}: H = {cfg.mpc.horizon}, max_iter {cfg.mpc.max_iter}")
        print(
            "| noise | loop | cost (median) | goal reached | plans applied late, ticks: median (max) "
            "| replans per tick | replan ms (median) | plant's late ticks | real-time factor |"
        )
        print("|---|---|---|---|---|---|---|---|---|")
        for r in measure(cfg, args):
            late = f"{r['lag_median']:g} ({r['lag_max']})" if "lag_max" in r else "0 (0)"
            print(
                f"| {r['noise']:g} | {r['loop']} | {r['cost']:.4g} | {r['reached']}/{r['episodes']} "
                f"| {late} | {r.get('replans_per_tick', 1):.2f} | {r.get('replan_ms', float('nan')):.1f} | "
                f"{r.get('late_ticks', 0)} | {r.get('real_time_factor', float('nan')):.2f} |"
            )


if __name__ == "__main__":
    main()
