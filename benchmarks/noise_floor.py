"""What a closed-loop goal test can say under process noise: references that no planner
enters, read from MPC run folders (``benchmarks/mpc_robots.py`` and ``experiments.run``
with ``--experiment.kind mpc`` write them).

Process noise is added to the state after every plant step, the last one included, and
the goal test judges the last state. So:

* **the last draw alone**: the share of draws x_N = x*_T + noise * N(0, I), at the offline
  optimum's last state (at the goal state for a hold task), that fail the task's goal test
  (``pipeline.goal_test``'s bound). A planner that ended exactly there before the last
  draw would still fail this often;
* **the LQR at the goal** (a task whose goal state is near an equilibrium: one step from
  (x_goal, u_ref) moves less than 0.01 in every coordinate, reported as ``goal_drift``; no
  point goals; a model whose state is [qpos, qvel] with nq = nv): u = clip(u_ref - K (x -
  x_goal)), K of the infinite-horizon discrete LQR of the task's Q and R on the black
  box's step linearised by central differences at (x_goal, u_ref); its closed loop from
  the task's start simulated on native MuJoCo in float64 (the run's model, the model
  plant) for the run's steps. Reported: under fresh draws of the same noise level (at most
  400 episodes), the share that pass the goal test and the task's cost (median, 10th-90th
  percentile); and **on the same plant and disturbances** as each controller of the run
  (the residuals x_{n+1} - step(x_n, u_n) of its stored closed loops, stepped on the
  run's plant file; every controller of a run shares them), its cost beside the
  controller's, episode by episode.

    python benchmarks/noise_floor.py RUN_FOLDER [RUN_FOLDER ...] [--noise 0 0.01]
        [--draws 4000] [--seed 0]
"""

from __future__ import annotations

import argparse
import os
import sys

_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, _ROOT)

EQUILIBRIUM_TOL = 1e-2  # the goal is near an equilibrium where one step from it moves less


def central_differences(step, x, u, eps: float = 1e-6):
    """A [nx, nx], B [nx, nu] of x' = step(x, u) by central differences."""
    import numpy as np

    A = np.stack([(step(x + eps * e, u) - step(x - eps * e, u)) / (2 * eps) for e in np.eye(x.size)], 1)
    B = np.stack([(step(x, u + eps * e) - step(x, u - eps * e)) / (2 * eps) for e in np.eye(u.size)], 1)
    return A, B


def native_step(m, substeps: int):
    """step(x [nq + nv], u [nu]) -> x' of ``substeps`` native mj_step calls (float64)."""
    import mujoco
    import numpy as np

    d = mujoco.MjData(m)

    def step(x, u):
        mujoco.mj_resetData(m, d)
        d.qpos[:], d.qvel[:], d.ctrl[:] = x[: m.nq], x[m.nq :], u
        for _ in range(substeps):
            mujoco.mj_step(m, d)
        return np.concatenate([d.qpos, d.qvel])

    return step


def lqr_gain(A, B, Q, R):
    """K [nu, nx] of the infinite-horizon discrete LQR."""
    import numpy as np
    import scipy.linalg

    P = scipy.linalg.solve_discrete_are(A, B, Q, R)
    return np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)


def floor(folder: str, noise: float, draws: int, seed: int) -> dict:
    """The references of the module docstring for the run in ``folder`` at ``noise``."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    from mjx_surrogate import tasks
    from mjx_surrogate.runs import pipeline
    from mjx_surrogate.runs.config import Config, from_dict
    from mjx_surrogate.runs.resolution import resolve
    from mjx_surrogate.runs.results import read_json

    cfg, system, task = resolve(from_dict(Config, read_json(os.path.join(folder, "config.json"))))
    X_star = np.load(os.path.join(folder, "arrays.npz"))["X_star"]
    tol = cfg.task.goal_tolerance
    goal = jax.jit(jax.vmap(lambda x: tasks.goal_cost(task, x)))  # moving targets at the end (T)
    start = float(tasks.goal_cost(task, jnp.asarray(task.x0), t=0))  # and at their start
    bound = tol * (start if start > 0 else pipeline.unit_goal_cost(task))
    k_last, k_lqr = jax.random.split(jax.random.key(seed))
    hold = start == 0
    last = (np.asarray(task.x_goal, float) if hold else X_star[-1]) + noise * np.asarray(
        jax.random.normal(k_last, (draws, X_star.shape[1]), X_star.dtype)
    )
    out = {
        "run": folder,
        "noise": noise,
        "bound": bound,
        "last_draw_fails": float(np.mean(goal(last) > bound)),
    }
    m = system.mj_model
    Q = np.asarray(tasks.weight_matrix(task.Q), float)
    if m is None or m.nq != m.nv or m.na or task.points is not None or not Q.any():
        return out
    steps = cfg.mpc.steps if cfg.mpc is not None else task.T
    substeps = max(1, round(float(system.dt) / m.opt.timestep))
    step = native_step(m, substeps)
    x_goal, u_ref = np.asarray(task.x_goal, float), np.asarray(task.u_ref, float)
    drift = float(np.max(np.abs(step(x_goal, u_ref) - x_goal)))
    out["goal_drift"] = drift
    if drift > EQUILIBRIUM_TOL:
        return out  # the goal is no equilibrium: no LQR holds it
    A, B = central_differences(step, x_goal, u_ref)
    K = lqr_gain(A, B, Q, np.asarray(task.R, float))
    lo, hi = np.asarray(task.u_min, float), np.asarray(task.u_max, float)
    x0 = np.asarray(task.x0, float)

    def lqr(W, on=step):  # W [episodes, steps, nx] on plant step ``on`` -> costs, passes [episodes]
        X, U = lqr_episodes(on, K, x0, x_goal, u_ref, lo, hi, W)
        J = jax.vmap(lambda x, u: tasks.trajectory_cost(task, x, u))(jnp.asarray(X), jnp.asarray(U))
        return np.asarray(J), np.asarray(goal(jnp.asarray(X[:, -1]))) <= bound

    n_ep = min(draws, 400)  # native episodes, one by one
    J, passes = lqr(noise * np.asarray(jax.random.normal(k_lqr, (n_ep, steps, x0.size)), float))
    out |= {
        "lqr_episodes": n_ep,
        "lqr_pass": float(np.mean(passes)),
        "lqr_cost_median": float(np.median(J)),
        "lqr_cost_p10_p90": [float(v) for v in np.percentile(J, [10, 90])],
        "paired": paired(folder, noise, lambda label: plant_step(folder, label, step, substeps), lqr),
    }
    return out


def lqr_episodes(step, K, x0, x_goal, u_ref, lo, hi, W):
    """The closed loops x_{n+1} = step(x_n, u_n) + W[i, n], u_n = clip(u_ref - K (x_n -
    x_goal), lo, hi) from x0, one per row of W [E, N, nx] -> X [E, N+1, nx], U [E, N, nu]."""
    import numpy as np

    E, N, nx = W.shape
    X, U = np.empty((E, N + 1, nx)), np.empty((E, N, u_ref.size))
    for i in range(E):
        X[i, 0] = x0
        for n in range(N):
            U[i, n] = np.clip(u_ref - K @ (X[i, n] - x_goal), lo, hi)
            X[i, n + 1] = step(X[i, n], U[i, n]) + W[i, n]
    return X, U


def residuals(step, X, U):
    """W [E, N, nx]: x_{n+1} - step(x_n, u_n) of closed loops X [E, N+1, nx], U [E, N, nu]."""
    import numpy as np

    return np.stack(
        [[X[i, n + 1] - step(X[i, n], U[i, n]) for n in range(U.shape[1])] for i in range(len(X))]
    )


def plant_step(folder: str, label: str, model_step, substeps: int):
    """The native step of plant ``label`` of the run in ``folder`` (the model's for
    "model"; else its compiled file ``plant_<slug>.mjb``), or None if the file is missing."""
    import mujoco

    from mjx_surrogate.systems.plant import parse_plant, plant_slug

    changes = parse_plant(label)
    if not changes:
        return model_step
    path = os.path.join(folder, f"plant_{plant_slug(changes)}.mjb")
    return native_step(mujoco.MjModel.from_binary_path(path), substeps) if os.path.exists(path) else None


def paired(folder: str, noise: float, step_of, lqr) -> list[dict]:
    """Each controller's episodes at ``noise`` on every plant against the LQR's (designed on
    the model; ``lqr``: (W, plant step) -> costs, passes) on the same plant and the same
    disturbances, recovered by :func:`residuals` from the stored closed loop with the
    plant's step (``step_of``: plant label -> step or None; every controller of a run sees
    the same draws)."""
    import numpy as np

    from mjx_surrogate.runs.results import read_json

    rows = read_json(os.path.join(folder, "metrics.json")).get("mpc_rows", [])
    arrays = np.load(os.path.join(folder, "arrays.npz"))
    out = []
    for r in rows:
        step = step_of(r["plant"])
        if step is None or r["process_noise"] != noise or "arrays" not in r:
            continue
        X, U = arrays[r["arrays"]["X"]], arrays[r["arrays"]["U"]]
        if not np.all(np.isfinite(X)):
            continue
        W = residuals(step, X, U)
        J, passes = lqr(W, step)
        costs = np.asarray([np.inf if c is None else c for c in r["costs"]], float)
        out.append(
            {
                "controller": r["controller"],
                "plant": r["plant"],
                "episodes": len(X),
                "cost_median": float(np.median(costs)),
                "lqr_cost_median": float(np.median(J)),
                "lqr_passes": int(np.sum(passes)),
                "at_most_lqr": int(np.sum(costs <= J)),
                "residual_rms": float(np.sqrt(np.mean(W**2))),
            }
        )
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("folders", nargs="+", help="MPC run folders (config.json, arrays.npz)")
    ap.add_argument(
        "--noise", type=float, nargs="+", default=[0.01], help="process noise levels (state units)"
    )
    ap.add_argument("--draws", type=int, default=4000, help="last-state draws (LQR episodes: at most 400)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    from mjx_surrogate.runtime import configure_runtime

    configure_runtime(x64=True)
    print(
        "| run | noise | goal bound | last draw alone fails | LQR at the goal: passes "
        "| LQR cost (median, p10-p90) |"
    )
    print("|---|---|---|---|---|---|")
    pairs = []
    for folder, noise in ((f, w) for f in args.folders for w in args.noise):
        r = floor(folder, noise, args.draws, args.seed)
        lqr = ("-", "-")
        if "lqr_pass" in r:
            lo, hi = r["lqr_cost_p10_p90"]
            lqr = (
                f"{100 * r['lqr_pass']:.0f} % of {r['lqr_episodes']}",
                f"{r['lqr_cost_median']:.3g} ({lo:.3g}-{hi:.3g})",
            )
        run = os.path.basename(os.path.normpath(folder))
        print(
            f"| {run} | {noise:g} | {r['bound']:.3g} | {100 * r['last_draw_fails']:.1f} % "
            f"| {lqr[0]} | {lqr[1]} |"
        )
        pairs += [p | {"run": run, "noise": noise} for p in r.get("paired", [])]
    if pairs:
        print("\nOn the same plant and disturbances (residuals of each run's closed loops):\n")
        print(
            "| run | plant | noise | controller | episodes | its cost (median) | LQR's cost (median) "
            "| episodes at most the LQR's cost | LQR passes | residual RMS |"
        )
        print("|---|---|---|---|---|---|---|---|---|---|")
        for p in pairs:
            print(
                f"| {p['run']} | {p['plant']} | {p['noise']:g} | {p['controller']} | {p['episodes']} "
                f"| {p['cost_median']:.4g} | {p['lqr_cost_median']:.4g} | {p['at_most_lqr']} "
                f"| {p['lqr_passes']} | {p['residual_rms']:.3g} |"
            )


if __name__ == "__main__":
    main()
