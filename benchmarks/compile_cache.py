"""Compile times of the CLI's solves, cold and from JAX's persistent compilation cache.

Each preset runs twice through ``python -m experiments.run PRESET --solver.max_iter 3``
(progress off), both runs with one new, empty ``MJX_SURROGATE_CACHE`` folder; the D2C and
exact-oracle ``compile_s`` (tracing + compiling, or loading, both programs of the chunked
solve) are read from each run's ``metrics.json``. Run on an idle machine:

    python benchmarks/compile_cache.py [--presets default pendulum_d2c cartpole_d2c ...] [--rounds N]
                                       [--extra "--system.name mjcf --system.mjcf_path robot.xml ..."]

``--extra`` appends the same command-line fields to every run (a user's model, say).
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import shlex
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PRESETS = ["default", "pendulum_d2c", "cartpole_d2c", "fish_d2c", "swimmer6_d2c", "swimmer15_d2c"]


def _run(preset: str, cache: str, out: str, extra: list[str]) -> tuple[dict, float]:
    env = dict(os.environ, MJX_SURROGATE_CACHE=cache)
    cmd = [sys.executable, "-m", "experiments.run"] + ([preset] if preset != "default" else [])
    cmd += ["--solver.max_iter", "3", "--experiment.no-progress", "--experiment.out-dir", out, *extra]
    t0 = time.perf_counter()
    subprocess.run(cmd, cwd=ROOT, env=env, check=True, capture_output=True)
    wall = time.perf_counter() - t0
    (path,) = sorted(glob.glob(os.path.join(out, "*", "metrics.json")))[-1:]
    return json.load(open(path)), wall


def _compile(metrics: dict, stage: str) -> str:
    value = (metrics.get(stage) or {}).get("compile_s")
    return "off" if value is None else f"{value:.1f}"


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--presets", nargs="+", default=PRESETS)
    ap.add_argument("--rounds", type=int, default=1, help="cold/cached pairs per preset")
    ap.add_argument("--extra", default="", help="command-line fields appended to every run")
    a = ap.parse_args(argv)
    if a.rounds < 1:
        ap.error(f"--rounds: must be at least 1, got {a.rounds}")
    print(
        "| preset | round | D2C compile, cold / cached (s) | exact oracle compile, cold / cached (s) "
        "| run wall, cold / cached (s) |"
    )
    print("|---|---|---|---|---|")
    for preset in a.presets:
        for r in range(1, a.rounds + 1):
            with tempfile.TemporaryDirectory() as tmp:
                cache = os.path.join(tmp, "cache")
                cold, w0 = _run(preset, cache, os.path.join(tmp, "a"), shlex.split(a.extra))
                warm, w1 = _run(preset, cache, os.path.join(tmp, "b"), shlex.split(a.extra))
            d2c = f"{_compile(cold, 'd2c')} / {_compile(warm, 'd2c')}"
            exact = f"{_compile(cold, 'exact')} / {_compile(warm, 'exact')}"
            label = f"{preset} {a.extra}".strip()
            print(f"| `{label}` | {r} | {d2c} | {exact} | {w0:.1f} / {w1:.1f} |", flush=True)


if __name__ == "__main__":
    main()
