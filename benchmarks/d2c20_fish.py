"""D2C 2.0's fish task on D2C 2.0's own fish: its stored optima replayed, this project's D2C run.

D2C 2.0 (github.com/karthikeyaparunandi/D2C-2.0 at commit 9d433d5) solved the fish task on
``models/fish_old.xml``: dm_control's fish with a time step of 0.005 s and no control limits.
It stored each run's controls and states (``experiments/fish/exp_K/fish_policy.txt``, K = 1..11)
and its cost after every iteration (``training_cost_data.txt``). Its cost is x'Qx + u'Ru, twice
this project's 0.5 (x'Qx + u'Ru) over the same stages; the tables give both.

1. Each run's controls are replayed on ``fish_old.xml`` with today's MuJoCo (5 physics steps a
   control step): the states against the stored ones, the cost against the last logged one.
2. The same controls on this project's fish (``mjx_surrogate/systems/fish.py``, time step 0.005
   as ``fish_d2c`` sets it) and on dm_control's current ``suite/fish.xml`` (time step set to
   0.005; its ctrlrange of +-1 clips them).
3. ``configs/fish_d2c.py``'s D2C (the same task, solver and identification) on ``fish_old.xml``
   and, with ``--dm-control-d2c``, on dm_control's fish, from ``--seeds`` random starts.

    python benchmarks/d2c20_fish.py [--d2c20 PATH] [--seeds 5] [--dm-control [--dm-control-d2c]]

PATH: a checkout of the D2C-2.0 repository; without it the files are downloaded from GitHub at
that commit into ``~/.cache/mjx_surrogate/d2c20`` (about 25 MB). The models are not committed.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import re
import sys
import time
import urllib.request

import numpy as np

_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, _ROOT)
sys.path.insert(0, os.path.join(_ROOT, "tests"))

COMMIT = "9d433d546e7c2c42e304fcea45684bfee2bf8bbb"
RUNS = range(1, 12)
SUBSTEPS = 5
CACHE = os.path.join(os.path.expanduser("~"), ".cache", "mjx_surrogate", "d2c20")


def _files() -> list[str]:
    names = ["models/fish_old.xml"]
    for k in RUNS:
        names += [f"experiments/fish/exp_{k}/{f}" for f in ("fish_policy.txt", "training_cost_data.txt")]
    return names


def fetch(root: str | None) -> str:
    """A folder holding D2C 2.0's fish files: ``root`` if given, else the cache (downloaded once)."""
    if root is not None:
        return root
    for name in _files():
        path = os.path.join(CACHE, name)
        if not os.path.exists(path):
            os.makedirs(os.path.dirname(path), exist_ok=True)
            url = f"https://raw.githubusercontent.com/karthikeyaparunandi/D2C-2.0/{COMMIT}/{name}"
            with urllib.request.urlopen(url, timeout=60) as r, open(path + ".tmp", "wb") as f:
                f.write(r.read())
            os.replace(path + ".tmp", path)
    return CACHE


def fish_old(root: str, out_dir: str) -> str:
    """``fish_old.xml`` without its visual includes and materials (files the repository does not
    hold; they change no dynamics), written to ``out_dir``; its path."""
    text = open(os.path.join(root, "models", "fish_old.xml")).read()
    text = re.sub(r"<include[^>]*/>", "", text)
    text = re.sub(r'\s+material="[^"]*"', "", text)
    path = os.path.join(out_dir, "fish_old.xml")
    with open(path, "w") as f:
        f.write(text)
    return path


def task_arrays(nq: int, nv: int, nu: int) -> dict:
    """``fish_d2c``'s task for a fish of these sizes: x0, x_goal [nx], Q, Q_f [nx, nx], R [nu, nu]."""
    from mjx_surrogate.systems import fish

    return fish.TASKS["fish_d2c"].build(nq, nv, nu)


def stored_run(root: str, k: int) -> tuple[np.ndarray, np.ndarray, float]:
    """Run k's controls U [600, 5], states X [600, 27] (x_1 .. x_T) and last logged cost."""
    with open(os.path.join(root, "experiments", "fish", f"exp_{k}", "fish_policy.txt")) as f:
        p = json.load(f)
    T = len(p["U"])
    U = np.array([np.ravel(p["U"][str(t)]) for t in range(T)])
    X = np.array([np.ravel(p["X"][str(t)]) for t in range(T)])
    with open(os.path.join(root, "experiments", "fish", f"exp_{k}", "training_cost_data.txt")) as f:
        logged = float(f.read().split()[-1])
    return U, X, logged


def replay(model, x0: np.ndarray, U: np.ndarray) -> np.ndarray:
    """x_1 .. x_T [T, nq + nv] of native MuJoCo from x0 under U [T, nu], SUBSTEPS steps each."""
    import mujoco

    d = mujoco.MjData(model)
    d.qpos[:], d.qvel[:] = x0[: model.nq], x0[model.nq :]
    X = np.empty((len(U), model.nq + model.nv))
    for t, u in enumerate(U):
        d.ctrl[:] = u
        mujoco.mj_step(model, d, nstep=SUBSTEPS)
        X[t] = np.concatenate([d.qpos, d.qvel])
    return X


def cost(x0, X, U, goal, q, q_f, r) -> float:
    """This project's cost 0.5 sum_t (e_t' Q e_t + u_t' R u_t) + 0.5 e_T' Q_f e_T (diagonal
    weights q, q_f, r); D2C 2.0's is twice it."""
    E = np.vstack([x0, X]) - goal
    return float(0.5 * ((E[:-1] ** 2 * q).sum() + (U**2 * r).sum() + (E[-1] ** 2 * q_f).sum()))


def d2c_config(path: str, t: dict, seed: int, timestep: float | None, max_iter: int | None = None):
    """``configs/fish_d2c.py`` with its system replaced by the MJCF at ``path`` (native,
    SUBSTEPS physics steps a control step) and its task ``t`` (:func:`task_arrays`) written out."""
    from configs.fish_d2c import CONFIG
    from mjx_surrogate.runs.config import SystemConfig, TaskConfig

    task = TaskConfig(
        preset="custom",
        T=t["T"],
        x0=tuple(t["x0"]),
        x_goal=tuple(t["x_goal"]),
        Q_diag=tuple(np.diag(t["Q"])),
        Q_f_diag=tuple(np.diag(t["Q_f"])),
        R_diag=tuple(np.diag(t["R"])),
        state_error="euclidean",
    )
    system = SystemConfig(name="mjcf", mjcf_path=path, backend="native", substeps=SUBSTEPS, timestep=timestep)
    experiment = dataclasses.replace(CONFIG.experiment, seed=seed, progress=False)
    solver = CONFIG.solver if max_iter is None else dataclasses.replace(CONFIG.solver, max_iter=max_iter)
    return dataclasses.replace(CONFIG, system=system, task=task, solver=solver, experiment=experiment)


def _solve(path: str, t: dict, seed: int, timestep: float | None, max_iter: int | None = None):
    from mjx_surrogate.runs import pipeline
    from mjx_surrogate.runs.resolution import resolve

    res = resolve(d2c_config(path, t, seed, timestep, max_iter))
    rc, system, task = res
    d2c = pipeline.solve_config(res)
    m, X = pipeline.summary(d2c.timed.out, system, task, rc.task.goal_tolerance)
    return d2c, m, np.asarray(X)


def solve(path: str, model, t: dict, seed: int, timestep: float | None, targets: dict) -> dict:
    """D2C on the model at ``path`` from the random start of ``seed``: its metrics, its
    controls' cost replayed here with ``mujoco.mj_step``, and for each target cost (this
    project's units) the first iteration at or below it and the run time to it (a second
    solve stopped at that iteration, compile apart)."""
    t0 = time.perf_counter()
    d2c, m, X = _solve(path, t, seed, timestep)
    out = d2c.timed.out
    U = np.asarray(out.U)
    q, q_f, r = np.diag(t["Q"]), np.diag(t["Q_f"]), np.diag(t["R"])
    replayed = cost(t["x0"], replay(model, t["x0"], U), U, t["x_goal"], q, q_f, r)
    history = np.asarray(out.cost_history)
    reached = {}
    for name, target in targets.items():
        below = np.flatnonzero(history <= target)
        if below.size == 0:
            reached[name] = None
            continue
        n = int(below[0])
        again, _, _ = _solve(path, t, seed, timestep, max_iter=n)
        reached[name] = {"iteration": n, "run_s": again.timed.run_s, "cost": float(again.timed.out.cost)}
    return {
        "seed": seed,
        "status": m["status"],
        "cost": m["cost"],
        "replayed_cost": replayed,
        "iterations": m["iterations"],
        "goal": m["goal"]["reached"],
        "final_xyz": [float(v) for v in X[-1, :3]],
        "run_s": d2c.timed.run_s,
        "compile_s": d2c.timed.compile_s,
        "reached": reached,
        "wall_s": time.perf_counter() - t0,
    }


def _models(root: str, out_dir: str, dm_control: bool) -> dict:
    """name -> (MjModel at time step 0.005, path or None): fish_old, this project's fish,
    dm_control's fish (if downloadable)."""
    import mujoco

    from mjx_surrogate.systems import fish

    path = fish_old(root, out_dir)
    models = {"fish_old.xml (D2C 2.0)": (mujoco.MjModel.from_xml_path(path), path)}
    ours = mujoco.MjModel.from_xml_string(fish.xml())
    ours.opt.timestep = 0.005
    models["this project's fish"] = (ours, None)
    if dm_control:
        from thirdparty import model_path

        dmc = model_path("dm_control", "fish.xml")
        if dmc is not None:
            m = mujoco.MjModel.from_xml_path(dmc)
            m.opt.timestep = 0.005
            models["dm_control suite/fish.xml"] = (m, dmc)
    return models


def _refuse(message: str) -> None:
    print(f"error: {message}", file=sys.stderr)
    sys.exit(2)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--d2c20", default=None, help="a checkout of D2C-2.0 (default: download)")
    ap.add_argument("--seeds", type=int, default=5, help="D2C random starts per model")
    ap.add_argument("--dm-control", action="store_true", help="also dm_control's fish.xml (pip download)")
    ap.add_argument("--dm-control-d2c", action="store_true", help="D2C on dm_control's fish.xml too")
    ap.add_argument("--json", default=None, help="write every figure to this file")
    a = ap.parse_args()
    if a.seeds < 0:
        _refuse(f"--seeds: must be >= 0, got {a.seeds}")
    if a.d2c20 is not None and not os.path.exists(os.path.join(a.d2c20, "models", "fish_old.xml")):
        _refuse(f"--d2c20: no models/fish_old.xml under {a.d2c20} (give a checkout of D2C-2.0)")
    from mjx_surrogate.runtime import configure_runtime

    configure_runtime(x64=True)
    import tempfile

    try:
        root = fetch(a.d2c20)
    except OSError as exc:
        _refuse(f"--d2c20: D2C 2.0's files could not be downloaded ({exc}); give a checkout of D2C-2.0")
    with tempfile.TemporaryDirectory(prefix="d2c20_fish_") as out_dir:
        _run(a, root, out_dir)


def _run(a: argparse.Namespace, root: str, out_dir: str) -> None:
    """The replays and D2C runs of :func:`main`, the stripped model written in ``out_dir``."""
    models = _models(root, out_dir, a.dm_control)
    m = next(iter(models.values()))[0]  # fish_old.xml: every fish here has its sizes
    t = task_arrays(m.nq, m.nv, m.nu)
    x0, goal = t["x0"], t["x_goal"]
    q, q_f, r = np.diag(t["Q"]), np.diag(t["Q_f"]), np.diag(t["R"])
    result: dict = {"replays": [], "d2c": {}}
    print("D2C 2.0's runs replayed (this project's cost; D2C 2.0's is twice it):\n")
    head = " | ".join(models)
    print(f"| run | logged (D2C 2.0's units) | {head} | max abs state error against the stored |")
    print("|---|---|" + "---|" * len(models) + "---|")
    for k in RUNS:
        U, X_stored, logged = stored_run(root, k)
        costs, err = [], None
        for name, (model, _) in models.items():
            X = replay(model, x0, U)
            costs.append(cost(x0, X, U, goal, q, q_f, r))
            if err is None:
                err = float(np.abs(X - X_stored).max())
        row = {"run": k, "logged": logged, "costs": dict(zip(models, costs)), "error": err}
        result["replays"].append(row)
        cells = " | ".join(f"{c:.2f}" for c in costs)
        print(f"| {k} | {logged:.2f} | {cells} | {err:.1e} |", flush=True)
    logged = [r["logged"] / 2 for r in result["replays"]]
    targets = {"D2C 2.0's published LLS-CD cost": logged[0], "the best of its 11 runs": min(logged)}
    print("\nThis project's D2C (configs/fish_d2c.py's settings) from random starts; the iteration")
    print("and run time at which it first reaches D2C 2.0's published LLS-CD cost (run 1, 401.74 in its")
    print(f"units, {logged[0]:.2f} here) and the best of its 11 runs ({min(logged):.2f} here):\n")
    print(
        "| model | seed | status, iterations | cost (D2C 2.0's units) | replayed | goal | final x, y, z "
        "| to the published: it., s | to the best: it., s | run s, compile s |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    files = [(name, model, path) for name, (model, path) in models.items() if path is not None]
    for name, model, path in files[: 1 + a.dm_control_d2c]:  # fish_old.xml, then dm_control's
        rows = result["d2c"][name] = []
        for seed in range(a.seeds):
            row = solve(path, model, t, seed, 0.005, targets)
            rows.append(row)
            xyz = ", ".join(f"{v:.3f}" for v in row["final_xyz"])
            to = [f"{v['iteration']}, {v['run_s']:.2f}" if v else "no" for v in row["reached"].values()]
            print(
                f"| {name} | {seed} | {row['status']}, {row['iterations']} | {row['cost']:.2f} "
                f"({2 * row['cost']:.2f}) | {row['replayed_cost']:.2f} | {'yes' if row['goal'] else 'no'} "
                f"| {xyz} | {to[0]} | {to[1]} | {row['run_s']:.1f}, {row['compile_s']:.1f} |",
                flush=True,
            )
    if a.json:
        with open(a.json, "w") as f:
            json.dump(result, f, indent=1)


if __name__ == "__main__":
    main()
