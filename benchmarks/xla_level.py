"""What XLA's backend optimisation level does to a native-backend solve: compile and run time
of ``solve_d2c`` on each preset (forced to the native backend) at each level, one process
per preset and level (no compile shared), compile apart from run, run the median of
``--repeats`` calls; the cost and iteration count show whether the iterates changed.

    python benchmarks/xla_level.py [--presets pendulum_d2c fish_d2c swimmer6_d2c]
                                   [--levels default 1 0] [--repeats 3]

A native program compiles on a model's first run (later runs load it from JAX's cache);
``System.compiler_options`` picks level 1 for them (docs/performance.md).
"""

from __future__ import annotations

import os as _os
import sys as _sys

_sys.path.insert(0, _os.path.dirname(_os.path.dirname(_os.path.abspath(__file__))))

import argparse
import dataclasses
import json
import subprocess


def one(preset: str, level: str, repeats: int) -> dict:
    """One cell, in this process."""
    from mjx_surrogate.runtime import configure_runtime

    configure_runtime(x64=True, compile_cache=False)
    import jax

    from experiments.run import load_config
    from mjx_surrogate.control.d2c import solve_d2c
    from mjx_surrogate.runs import pipeline
    from mjx_surrogate.runs.resolution import resolve, solver_params
    from mjx_surrogate.timing import compile_then_run

    cfg = load_config(preset)
    cfg = dataclasses.replace(cfg, system=dataclasses.replace(cfg.system, backend="native"))
    res = resolve(cfg)
    s, task, rc = res.system, res.task, res.config
    params, sid = solver_params(rc)
    U0 = pipeline.start_controls(s, task, rc.solver.init, rc.solver.init_scale, jax.random.key(0))
    options = None if level == "default" else {"xla_backend_optimization_level": int(level)}
    # the lowering of a plain jit: solve_d2c's own options (System.compiler_options) would
    # otherwise be merged into the compile call's
    fn = jax.jit(solve_d2c.__wrapped__, static_argnames=("system",))
    args = (task, U0, jax.random.key(1), params, sid)
    t = compile_then_run(fn, (s,), args, repeats, compiler_options=options)
    return dict(
        preset=preset,
        level=level,
        compile_s=t.compile_s,
        run_s=t.run_s,
        cost=float(t.out.cost),
        iterations=int(t.out.iterations),
    )


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--presets", nargs="+", default=["pendulum_d2c", "fish_d2c", "swimmer6_d2c"])
    ap.add_argument("--levels", nargs="+", default=["default", "1", "0"])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--one", nargs=2, metavar=("PRESET", "LEVEL"), help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.one:
        print(json.dumps(one(a.one[0], a.one[1], a.repeats)))
        return 0
    print("| native solve | level | compile s | run s | cost | iterations |")
    print("|---|---|---|---|---|---|")
    for preset in a.presets:
        for level in a.levels:
            cmd = [_sys.executable, _os.path.abspath(__file__), "--one", preset, level]
            cmd += ["--repeats", str(a.repeats)]
            out = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
            r = json.loads(out.strip().splitlines()[-1])
            print(
                f"| {preset} | {level} | {r['compile_s']:.2f} | {r['run_s']:.3f} | "
                f"{r['cost']:.6g} | {r['iterations']} |",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
