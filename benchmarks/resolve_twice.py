"""A notebook's second run of the same config, in the same process: resolve, then the D2C
solve as the command line makes it, twice.

    python benchmarks/resolve_twice.py [--task "reacher (reach)"]

A task of ``benchmarks/robots.py`` (a model downloaded at run time, resolved from its file
each time). Systems are kept by their content (``systems.system.build_system``), so the
second resolution gets the first's System and every program jitted on it; prints each
round's compile and run seconds, whether the System is the same object, and the cost.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, _ROOT)
sys.path.insert(0, os.path.join(_ROOT, "benchmarks"))
sys.path.insert(0, os.path.join(_ROOT, "tests"))


def main() -> None:
    import robots

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--task", default="reacher (reach)", choices=sorted(robots.TASKS))
    a = ap.parse_args()

    from mjx_surrogate.runtime import configure_runtime

    configure_runtime(x64=True)
    from mjx_surrogate.runs import pipeline
    from mjx_surrogate.runs.resolution import resolve

    print("| round | same System | compile s | run s | resolve + solve s | cost |\n|---|---|---|---|---|---|")
    first = None
    for i in (1, 2):
        cfg = robots.task_config(a.task)
        if cfg is None:
            sys.exit(f"{a.task}: its model could not be downloaded")
        t0 = time.perf_counter()
        res = resolve(cfg)
        solved = pipeline.solve_config(res)
        wall = time.perf_counter() - t0
        same = "-" if first is None else ("yes" if res.system is first else "no")
        t = solved.timed
        print(f"| {i} | {same} | {t.compile_s:.2f} | {t.run_s:.2f} | {wall:.2f} | {float(t.out.cost):.8g} |")
        first = res.system


if __name__ == "__main__":
    main()
