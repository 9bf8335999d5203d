"""D2C on models we did not write, against the finite-difference oracle.

The cases of ``tests/test_thirdparty.py`` (dm_control and gymnasium MJCF files, fetched
with ``pip download --no-deps`` into a cache, never installed): native backend, float64,
zero initial controls, the models' own ctrlrange, 60 iterations at most. For each model:
D2C status, cost, iterations, goal test, run and compile time apart; the FD oracle's cost
from the same start and the gap; with ``--seeds N``, the spread of D2C's cost over N keys.

    python benchmarks/thirdparty.py [--seeds 4] [--models hopper ant]

With ``--hold``, instead: every dm_control suite model and gymnasium asset with controls
through its ``hold`` task and the documented defaults, one D2C iteration each, checked as
the suite checks its chosen few (``tests/test_thirdparty.py``'s ``check_hold_solve``: the
cost never rises, the controls stay in the ctrlrange, the cost replays with
``mujoco.rollout``, the verdict is true); a row per model, ``FAILED`` and the failing check
where one fails (exit status 1).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time

_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, _ROOT)
sys.path.insert(0, os.path.join(_ROOT, "tests"))


def _timed(fn, *args):
    t0 = time.perf_counter()
    compiled = fn.lower(*args).compile()
    t1 = time.perf_counter()
    out = compiled(*args)
    float(out.cost)
    return out, t1 - t0, time.perf_counter() - t1


def _hold_sweep(models: list[str] | None) -> int:
    """The hold sweep (``--hold``); returns the exit status."""
    from test_thirdparty import HOLD_MODELS, check_hold_solve, hold_config

    print("| model | status | cost (start) | goal reached | checks | s (compile included) |")
    print("|---|---|---|---|---|---|")
    failed = 0
    for model in HOLD_MODELS:
        if models and not any(m in model for m in models):
            continue
        if hold_config(model) is None:
            print(f"| {model} | wheel not downloadable |")
            continue
        t0 = time.perf_counter()
        try:
            m = check_hold_solve(model)
            row = f"{m['status']} | {m['cost']:.4g} ({m['cost_start']:.4g}) "
            row += f"| {'yes' if m['goal']['reached'] else 'no'} | passed"
        except AssertionError as e:
            failed += 1
            row = f"| | | FAILED: {str(e).splitlines()[0][:120]}"
        print(f"| {model} | {row} | {time.perf_counter() - t0:.1f} |", flush=True)
    return 1 if failed else 0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--seeds", type=int, default=1, help="D2C keys per model (spread of the cost)")
    ap.add_argument("--models", nargs="*", default=None, help="substrings of case names (default: all)")
    ap.add_argument("--hold", action="store_true", help="every suite model's hold task, one D2C iteration")
    a = ap.parse_args()
    from mjx_surrogate.runtime import configure_runtime

    configure_runtime(x64=True)
    if a.hold:
        sys.exit(_hold_sweep(a.models))
    import functools

    import jax
    import jax.numpy as jnp
    from test_thirdparty import CASES, case_config

    from mjx_surrogate.control.d2c import solve_d2c, solve_exact
    from mjx_surrogate.runs.pipeline import summary
    from mjx_surrogate.runs.resolution import resolve, solver_params

    print(
        "| model | nx, nu | contacts | D2C status | D2C cost | iterations | goal reached "
        "| D2C run s (compile s) | FD-oracle cost (status) | gap |"
        + (" D2C cost over seeds |" if a.seeds > 1 else "")
    )
    print("|---" * (10 + (a.seeds > 1)) + "|")
    for name, (package, *_, contacts) in CASES.items():
        if a.models and not any(m in name for m in a.models):
            continue
        cfg = case_config(name)
        if cfg is None:
            print(f"| {name} | {package} wheel not downloadable |")
            continue
        # 60 iterations everywhere (the test runs the ant for fewer)
        cfg = dataclasses.replace(cfg, solver=dataclasses.replace(cfg.solver, max_iter=60))
        res = resolve(cfg)
        s, tk = res.system, res.task
        params, sid = solver_params(res.config)
        U0 = jnp.zeros((tk.T, s.nu))
        d2c = functools.partial(solve_d2c, s)
        d, c_d, r_d = _timed(jax.jit(d2c), tk, U0, jax.random.key(0), params, sid)
        oracle = jax.jit(lambda tk, U0, p: solve_exact(s, tk, U0, p, jacobians="finite_difference"))
        o, _, _ = _timed(oracle, tk, U0, params)
        m, _ = summary(d, s, tk, res.config.task.goal_tolerance)
        mo, _ = summary(o, s, tk, res.config.task.goal_tolerance)
        gap = 100 * (float(d.cost) / float(o.cost) - 1)
        row = (
            f"| {name} ({package}) | {s.nx}, {s.nu} | {'yes' if contacts else 'no'} | {m['status']} "
            f"| {float(d.cost):.5g} | {int(d.iterations)} | {'yes' if m['goal']['reached'] else 'no'} "
            f"| {r_d:.2f} ({c_d:.1f}) | {float(o.cost):.5g} ({mo['status']}) | {gap:+.2g} % |"
        )
        if a.seeds > 1:
            costs = [float(jax.jit(d2c)(tk, U0, jax.random.key(i), params, sid).cost) for i in range(a.seeds)]
            row += f" {min(costs):.4g} .. {max(costs):.4g} |"
        print(row, flush=True)


if __name__ == "__main__":
    main()
