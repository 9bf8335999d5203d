"""Trace, compile and run time of the MJX physics' batched programs: the exact oracle's
Jacobians and the batched step as the engine builds them (a loop over the substeps of the
batched physics step, ``backend_mjx.MjxPhysics``) against ``vmap(jacfwd(step))`` and
``vmap(step)`` of the control step's loop.

    python benchmarks/mjx_programs.py [--systems fish cartpole] [--repeats 7]

Float64, the persistent compilation cache off; each program is traced, lowered and
compiled in a fresh process (an earlier trace in the same process would warm the MJX
step's inner ``jit`` caches); run times are medians of ``--repeats`` runs of both forms,
alternating in one process. States near the
model's rest pose. Same numbers either way (checked here: maximum absolute difference).
Run on an idle machine: XLA's compile times vary by a quarter from run to run.
"""

from __future__ import annotations

import os as _os
import sys as _sys

_sys.path.insert(0, _os.path.dirname(_os.path.dirname(_os.path.abspath(__file__))))

import argparse
import json
import subprocess
import tempfile

FORMS = {  # program -> (the engine's form, the reference form)
    "jacobians": ("loop", "jacfwd"),
    "step": ("loop", "vmap"),
}


def _program(system: str, program: str, form: str, T: int, batch: int):
    """(jitted function, X, U) of one program."""
    import jax

    jax.config.update("jax_enable_x64", True)
    jax.config.update("jax_enable_compilation_cache", False)
    import jax.numpy as jnp
    import numpy as np

    from mjx_surrogate.systems import backend_mjx, make_system

    s = make_system(system, "native")
    physics = backend_mjx.make_mjx_physics(s.mj_model, s.substeps)
    n = T if program == "jacobians" else batch
    rng = np.random.default_rng(0)
    X = np.tile(np.concatenate([s.mj_model.qpos0, np.zeros(s.nx - s.mj_model.nq)]), (n, 1))
    X = jnp.asarray(X + 0.01 * rng.standard_normal(X.shape))
    U = jnp.asarray(0.1 * rng.standard_normal((n, s.nu)))
    if program == "jacobians" and form == "loop":
        f = physics.jacobians_batch
    elif program == "jacobians":
        f = jax.jit(jax.vmap(jax.jacfwd(physics.step, argnums=(0, 1))))
    else:
        f = physics.step_batch if form == "loop" else jax.jit(jax.vmap(physics.step))
    return f, X, U


def measure(system: str, program: str, form: str, T: int, batch: int, out: str) -> dict:
    """Trace, lower and compile one program in this process; its result saved to ``out``."""
    import time

    import jax
    import numpy as np

    f, X, U = _program(system, program, form, T, batch)
    t0 = time.perf_counter()
    traced = f.trace(X, U)
    t1 = time.perf_counter()
    lowered = traced.lower()
    t2 = time.perf_counter()
    compiled = lowered.compile()
    t3 = time.perf_counter()
    result = jax.block_until_ready(compiled(X, U))
    np.save(out, np.concatenate([np.ravel(r) for r in jax.tree.leaves(result)]))
    return {"trace": t1 - t0, "lower": t2 - t1, "compile": t3 - t2}


def run_times(system: str, program: str, T: int, batch: int, repeats: int) -> dict:
    """Median run time of both forms of a program, compiled in this process and run
    alternately (separate processes differ by up to a third in run time)."""
    import time

    import jax
    import numpy as np

    fns = {form: _program(system, program, form, T, batch) for form in FORMS[program]}
    for f, X, U in fns.values():
        jax.block_until_ready(f(X, U))
    times = {form: [] for form in fns}
    for _ in range(repeats):
        for form, (f, X, U) in fns.items():
            t = time.perf_counter()
            jax.block_until_ready(f(X, U))
            times[form].append(time.perf_counter() - t)
    return {form: float(np.median(v)) for form, v in times.items()}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--systems", nargs="+", default=["fish", "cartpole"])
    ap.add_argument("--T", type=int, default=None, help="Jacobian points (default: fish 600, else 30)")
    ap.add_argument("--batch", type=int, default=8, help="batched step's size (the line search's trials)")
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--one", nargs=4, help=argparse.SUPPRESS)  # system program form out: a child process
    ap.add_argument("--runs", nargs=2, help=argparse.SUPPRESS)  # system program: a child process
    a = ap.parse_args(argv)
    from mjx_surrogate.errors import ConfigError
    from mjx_surrogate.systems.registry import default_config

    for name in a.systems:
        try:
            default_config(name)
        except ConfigError as e:
            ap.error(f"--systems: {e}")
    for field in ("T", "batch", "repeats"):
        if getattr(a, field) is not None and getattr(a, field) < 1:
            ap.error(f"--{field}: must be at least 1, got {getattr(a, field)}")
    T = lambda system: a.T or (600 if system == "fish" else 30)  # noqa: E731
    if a.one:
        system, program, form, out = a.one
        print(json.dumps(measure(system, program, form, T(system), a.batch, out)))
        return
    if a.runs:
        system, program = a.runs
        print(json.dumps(run_times(system, program, T(system), a.batch, a.repeats)))
        return
    import numpy as np

    print("| system | program | form | trace s | lower s | compile s | run (median) | max abs diff |")
    print("|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for system in a.systems:
            for program, forms in FORMS.items():
                rows, results = [], []
                for form in forms:
                    out = _os.path.join(tmp, f"{system}_{program}_{form}.npy")
                    rows.append((form, _child(a, ["--one", system, program, form, out])))
                    results.append(np.load(out))
                diff = float(np.max(np.abs(results[0] - results[1])))
                runs = _child(a, ["--runs", system, program])
                for form, r in rows:
                    run = f"{runs[form] * 1e3:.2f} ms"
                    print(
                        f"| {system} | {program} | {form} | {r['trace']:.2f} | {r['lower']:.2f} "
                        f"| {r['compile']:.2f} | {run} | {diff:.1e} |",
                        flush=True,
                    )


def _child(a, args: list[str]) -> dict:
    """Run this script with ``args`` in a fresh process; its JSON answer."""
    cmd = [_sys.executable, _os.path.abspath(__file__)] + args
    cmd += ["--batch", str(a.batch), "--repeats", str(a.repeats)] + (["--T", str(a.T)] if a.T else [])
    proc = subprocess.run(cmd, check=True, capture_output=True, text=True)
    return json.loads(proc.stdout.strip().splitlines()[-1])


if __name__ == "__main__":
    main()
