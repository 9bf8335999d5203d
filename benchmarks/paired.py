"""Run time of one D2C solve in two checkouts of this repository, measured in alternation.

This machine's speed drifts by 10-40 % within minutes, so timings of two commits taken one
after the other cannot resolve a few per cent. Here two processes, one per checkout, each
compile the solve of ``benchmarks/d2c.py``'s ``bench`` (that checkout's own code and
presets), then take turns: one solve of A, one of B, and so on, never both at once. The
ratio of each pair's times is free of the slow drift.

    python benchmarks/paired.py OTHER_CHECKOUT [--system swimmer6] [--pairs 30]
                                [--max-iter N] [--this .]

A is ``OTHER_CHECKOUT`` (e.g. ``git worktree add /tmp/base 1d4224a``), B this checkout.
Prints both solves' cost and iterations (they should agree where the change keeps the
numbers) and the paired ratio B / A: median, mean and a 95 % interval of the mean.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time


def _pass_turn(folder: str, to: str) -> None:
    tmp = os.path.join(folder, "turn.tmp")
    with open(tmp, "w") as f:
        f.write(to)
    os.replace(tmp, os.path.join(folder, "turn"))


def _wait(predicate) -> None:
    while not predicate():
        time.sleep(0.005)


def worker(
    checkout: str, me: str, other: str, folder: str, system: str, pairs: int, max_iter: int | None
) -> None:
    """One side: compile through that checkout's ``bench``, then time a solve on each turn."""
    for path in (checkout, os.path.join(checkout, "tests"), os.path.join(checkout, "benchmarks")):
        sys.path.insert(0, path)
    os.chdir(checkout)
    from mjx_surrogate.runtime import configure_runtime

    configure_runtime()
    import jax

    import mjx_surrogate.timing as timing

    def in_turns(
        fn,
        static_args,
        dynamic_args,
        repeats=1,
        static_kwargs=None,
        dynamic_kwargs=None,
        compiler_options=None,
    ):
        kw = dynamic_kwargs or {}
        t0 = time.perf_counter()
        compiled = fn.lower(*static_args, *dynamic_args, **(static_kwargs or {}), **kw).compile(
            compiler_options
        )
        compile_s = time.perf_counter() - t0
        out = jax.block_until_ready(compiled(*dynamic_args, **kw))  # a first call, untimed
        open(os.path.join(folder, f"ready-{me}"), "w").close()
        _wait(lambda: os.path.exists(os.path.join(folder, f"ready-{other}")))
        times = []
        for _ in range(pairs):
            _wait(lambda: open(os.path.join(folder, "turn")).read() == me)
            t = time.perf_counter()
            out = jax.block_until_ready(compiled(*dynamic_args, **kw))
            times.append(time.perf_counter() - t)
            _pass_turn(folder, other)
        result = {
            "times": times,
            "compile_s": compile_s,
            "cost": float(out.cost),
            "iterations": int(out.iterations),
        }
        with open(os.path.join(folder, f"{me}.json"), "w") as f:
            json.dump(result, f)
        return timing.Timed(out, compile_s, statistics.median(times))

    timing.compile_then_run = in_turns  # bench() imports it when called
    spec = importlib.util.spec_from_file_location(
        "checkout_d2c", os.path.join(checkout, "benchmarks", "d2c.py")
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module.bench(system, "auto", max_iter, False, False)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("other", help="the checkout to compare with (A)")
    ap.add_argument("--this", default=os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    ap.add_argument("--system", default="swimmer6", help="a benchmarks/d2c.py system")
    ap.add_argument("--pairs", type=int, default=30)
    ap.add_argument("--max-iter", type=int, default=None, help="the preset's if not given")
    ap.add_argument(
        "--worker", nargs=4, metavar=("CHECKOUT", "ME", "OTHER", "FOLDER"), help=argparse.SUPPRESS
    )
    a = ap.parse_args()
    if a.worker:
        worker(*a.worker, a.system, a.pairs, a.max_iter)
        return
    if a.pairs < 2:
        ap.error(f"--pairs: {a.pairs} is too few; at least 2 (an interval needs two ratios)")
    for field, path in (("other", a.other), ("--this", a.this)):
        if not os.path.isfile(os.path.join(path, "benchmarks", "d2c.py")):
            ap.error(f"{field}: {path!r} is not a checkout of this repository (no benchmarks/d2c.py)")
        if not os.path.isfile(os.path.join(path, "configs", f"{a.system}_d2c.py")):
            ap.error(f"--system: {a.system!r} has no configs/{a.system}_d2c.py in {path!r}")
    with tempfile.TemporaryDirectory() as folder:
        _pass_turn(folder, "A")
        common = ["--system", a.system, "--pairs", str(a.pairs)]
        common += ["--max-iter", str(a.max_iter)] if a.max_iter else []
        procs = [
            subprocess.Popen([sys.executable, __file__, "x", *common, "--worker", path, me, other, folder])
            for path, me, other in ((os.path.abspath(a.other), "A", "B"), (os.path.abspath(a.this), "B", "A"))
        ]
        while all(p.poll() is None for p in procs):
            time.sleep(0.2)
        if any(p.returncode for p in procs if p.poll() is not None):
            for p in procs:  # the other one would wait for its turn forever
                p.kill()
            sys.exit("a worker failed")
        for p in procs:
            p.wait()
        if any(p.returncode for p in procs):
            sys.exit("a worker failed")
        A, B = (json.load(open(os.path.join(folder, f"{k}.json"))) for k in "AB")
    ratios = [b / x for x, b in zip(A["times"], B["times"])]
    half = 1.96 * statistics.stdev(ratios) / len(ratios) ** 0.5
    mean = statistics.mean(ratios)
    for k, r in (("A", A), ("B", B)):
        print(
            f"{k}: cost {r['cost']!r}, {r['iterations']} iterations, compile {r['compile_s']:.1f} s, "
            f"median run {statistics.median(r['times']):.3f} s"
        )
    print(
        f"{a.system}: B / A over {len(ratios)} pairs: median {statistics.median(ratios):.4f}, "
        f"mean {mean:.4f} (95 % interval {mean - half:.4f} - {mean + half:.4f})"
    )


if __name__ == "__main__":
    main()
