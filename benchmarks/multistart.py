"""Several starts on a host black box: one after another (``lax.map``, the default there)
against in lockstep (``vmap``), and against one solve, compile apart.

    python benchmarks/multistart.py [--preset swimmer15_d2c] [--starts 5] [--max-iter 40]

The preset's system, task and solver settings (its native backend), D2C from ``--starts``
random starts of ``solver.init_scale`` (keys from the preset's seed) for at most
``--max-iter`` iterations, through :func:`mjx_surrogate.control.chunked.solve` as a run
makes it. Lockstep is forced by replacing ``d2c.in_lockstep`` before the program is
traced. Prints, per way: run seconds (best of ``--repeats``), seconds per start, the
black-box control steps counted (``effort.multistart_steps``) and the starts' costs and
iterations, which the two ways must share (to round-off).
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import sys

_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, _ROOT)


def _run(res, U0s, key, params, sysid, repeats: int) -> tuple[object, float]:
    import jax

    from mjx_surrogate.control import chunked

    _, system, task = res
    best, out = float("inf"), None
    for _ in range(repeats):  # chunked.solve times its compile apart
        timed = chunked.solve(system, task, U0s, key, params, sysid, "d2c")
        best, out = min(best, timed.run_s), jax.block_until_ready(timed.out)
    return out, best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preset", default="swimmer15_d2c")
    ap.add_argument("--starts", type=int, default=5)
    ap.add_argument("--max-iter", type=int, default=40)
    ap.add_argument("--repeats", type=int, default=1)
    a = ap.parse_args()
    if a.starts < 2 or a.max_iter < 1 or a.repeats < 1:
        ap.error("--starts >= 2, --max-iter >= 1, --repeats >= 1")

    import dataclasses

    from mjx_surrogate.runtime import configure_runtime

    configure_runtime(x64=True)
    import jax
    import numpy as np

    from mjx_surrogate.control import d2c
    from mjx_surrogate.control.effort import multistart_steps, steps_per_identification
    from mjx_surrogate.identification import sysid as sid
    from mjx_surrogate.runs import pipeline
    from mjx_surrogate.runs.resolution import resolve, solver_params

    cfg = importlib.import_module(f"configs.{a.preset}").CONFIG
    cfg = dataclasses.replace(cfg, solver=dataclasses.replace(cfg.solver, max_iter=a.max_iter))
    res = resolve(cfg)
    rc, system, task = res
    params, sysid = solver_params(rc, False)
    k_init, k_d2c, _, _ = pipeline.experiment_keys(rc.experiment.seed)
    U0s = pipeline.start_controls(system, task, rc.solver.init, rc.solver.init_scale, k_init, a.starts)
    per_id = steps_per_identification(sysid, task.T, system.nu)
    fine = sid.fine_params(sysid) is not None
    rows = {}
    for way, lockstep in (("one after another (lax.map)", False), ("lockstep (vmap)", True)):
        d2c.in_lockstep = lambda s, _l=lockstep: _l  # noqa: E731  (read when the program is traced)
        jax.clear_caches()
        out, run_s = _run(res, U0s, k_d2c, params, sysid, a.repeats)
        steps = multistart_steps(
            np.asarray(out.iterations),
            np.asarray(out.identified),
            task.T,
            params.n_alphas,
            per_id,
            fine,
            lockstep,
        )
        rows[way] = {
            "run_s": run_s,
            "s_per_start": run_s / a.starts,
            "simulated_steps": steps,
            "costs": [float(c) for c in np.asarray(out.costs)],
            "iterations": [int(i) for i in np.asarray(out.iterations)],
        }
    one = (
        pipeline.start_controls(system, task, rc.solver.init, rc.solver.init_scale, k_init, a.starts)[0],
        jax.random.split(k_d2c, a.starts)[0],
    )
    from mjx_surrogate.control import chunked

    single = [chunked.solve(system, task, *one, params, sysid, "d2c") for _ in range(a.repeats)]
    rows["one start (start 0 alone)"] = {"run_s": min(t.run_s for t in single)}
    print(
        f"{a.preset} ({system.backend}, nx {system.nx}, nu {system.nu}, T {task.T}), {a.starts} starts, "
        f"at most {a.max_iter} iterations"
    )
    print("| way | run s | s per start | black-box control steps | iterations per start |")
    print("|---|---|---|---|---|")
    for way, r in rows.items():
        its = ", ".join(map(str, r.get("iterations", [])))
        per_start, steps = r.get("s_per_start", r["run_s"]), r.get("simulated_steps", "-")
        print(f"| {way} | {r['run_s']:.2f} | {per_start:.2f} | {steps} | {its} |")
    print("RESULT " + json.dumps(rows))


if __name__ == "__main__":
    main()
