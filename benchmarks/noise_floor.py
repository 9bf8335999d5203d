"""What a closed-loop goal test can say under process noise: two references that no
planner enters, read from MPC run folders (``benchmarks/mpc_robots.py`` writes them).

Process noise is added to the state after every plant step, the last one included, and
the goal test judges the last state. So:

* **the last draw alone**: the share of draws x_N = x*_T + noise * N(0, I), at the offline
  optimum's last state (at the goal state for a hold task), that fail the task's goal test
  (``pipeline.goal_test``'s bound). A planner that ended exactly there before the last
  draw would still fail this often;
* **the LQR at the goal** (a hold task, whose start is its goal, on a model whose state is
  [qpos, qvel] with nq = nv): u = u_ref - K (x - x_goal), K of the infinite-horizon
  discrete LQR of the task's Q and R on the black box's step linearised by central
  differences at (x_goal, u_ref); its closed loop simulated on native MuJoCo in float64
  (the run's model, the model plant) for the run's steps under the same noise level.
  Reported: the share of episodes that pass the goal test and the task's cost (median,
  10th-90th percentile). For small deviations this policy is near the best any planner
  can do on the task's own cost.

    python benchmarks/noise_floor.py RUN_FOLDER [RUN_FOLDER ...] [--noise 0.01]
        [--draws 4000] [--seed 0]
"""

from __future__ import annotations

import argparse
import os
import sys

_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, _ROOT)


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
    """The two references of the module docstring for the run in ``folder``."""
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
    goal = jax.jit(jax.vmap(lambda x: tasks.goal_cost(task, x)))
    start = float(goal(jnp.asarray(task.x0)[None])[0])
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
    if not hold or m is None or m.nq != m.nv or m.na:
        return out
    steps = cfg.mpc.steps if cfg.mpc is not None else task.T
    substeps = max(1, round(float(system.dt) / m.opt.timestep))
    step = native_step(m, substeps)
    x_goal, u_ref = np.asarray(task.x_goal, float), np.asarray(task.u_ref, float)
    A, B = central_differences(step, x_goal, u_ref)
    K = lqr_gain(A, B, np.asarray(task.Q, float), np.asarray(task.R, float))
    n_ep = min(draws, 400)  # native episodes, one by one
    W = noise * np.asarray(jax.random.normal(k_lqr, (n_ep, steps, A.shape[0])), float)
    lo, hi = np.asarray(task.u_min, float), np.asarray(task.u_max, float)
    X = np.empty((n_ep, steps + 1, A.shape[0]))
    U = np.empty((n_ep, steps, B.shape[1]))
    for i in range(n_ep):
        X[i, 0] = np.asarray(task.x0, float)
        for n in range(steps):
            U[i, n] = np.clip(u_ref - K @ (X[i, n] - x_goal), lo, hi)
            X[i, n + 1] = step(X[i, n], U[i, n]) + W[i, n]
    J = np.asarray(jax.vmap(lambda x, u: tasks.trajectory_cost(task, x, u))(jnp.asarray(X), jnp.asarray(U)))
    passes = np.asarray(goal(jnp.asarray(X[:, -1]))) <= bound
    out |= {
        "lqr_episodes": n_ep,
        "lqr_pass": float(np.mean(passes)),
        "lqr_cost_median": float(np.median(J)),
        "lqr_cost_p10_p90": [float(v) for v in np.percentile(J, [10, 90])],
    }
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("folders", nargs="+", help="MPC run folders (config.json, arrays.npz)")
    ap.add_argument("--noise", type=float, default=0.01, help="process noise level (state units)")
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
    for folder in args.folders:
        r = floor(folder, args.noise, args.draws, args.seed)
        lqr = (
            (
                f"{100 * r['lqr_pass']:.0f} % of {r['lqr_episodes']}",
                f"{r['lqr_cost_median']:.3g} ({r['lqr_cost_p10_p90'][0]:.3g}-{r['lqr_cost_p10_p90'][1]:.3g})",
            )
            if "lqr_pass" in r
            else ("-", "-")
        )
        print(
            f"| {os.path.basename(os.path.normpath(folder))} | {r['noise']:g} | {r['bound']:.3g} | "
            f"{100 * r['last_draw_fails']:.1f} % | {lqr[0]} | {lqr[1]} |"
        )


if __name__ == "__main__":
    main()
