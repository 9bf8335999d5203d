"""Where the test suite's time goes: a pytest plugin and its summary.

Record (each xdist worker writes ``DIR/profile-<run>-<pid>.json``)::

    SUITE_PROFILE_DIR=DIR python -m pytest -q -n 2 -p benchmarks.suite_profile

Summarise::

    python -m benchmarks.suite_profile DIR [--top 30]

Per test: wall time, CPU time of the test process and of the subprocesses it waited for
(``resource.getrusage``), the wall time in which neither ran (waiting), and JAX's own
compile events in the test process: tracing (``jaxpr_trace_duration``), lowering to MLIR
and XLA compilation, with the number of programs compiled and how many took under 0.1 s,
and the time Python's garbage collector ran in the test process (``gc.callbacks``). A
program loaded from the persistent compilation cache is not an XLA compile. Work done in a
subprocess counts in its CPU time only. A folder may hold several runs: the summary reads
the newest; files and tests are named short (``d2c::name`` for ``tests/test_d2c.py::test_name``).
"""

from __future__ import annotations

import argparse
import collections
import gc
import glob
import json
import os
import resource
import time
import uuid

import pytest

EVENTS = {
    "/jax/core/compile/jaxpr_trace_duration": "trace_s",
    "/jax/core/compile/jaxpr_to_mlir_module_duration": "lower_s",
    "/jax/core/compile/backend_compile_duration": "compile_s",
}
SMALL_S = 0.1
FIELDS = (
    "wall_s",
    "cpu_s",
    "subprocess_cpu_s",
    "compile_s",
    "trace_s",
    "lower_s",
    "programs",
    "small_programs",
    "gc_s",
)
_current: list[str | None] = [None]
_records: dict[str, dict[str, float]] = collections.defaultdict(lambda: dict.fromkeys(FIELDS, 0.0))


def _on_event(event: str, duration: float, **kwargs) -> None:
    field, test = EVENTS.get(event), _current[0]
    if field is None or test is None:
        return
    rec = _records[test]
    rec[field] += duration
    if field == "compile_s":
        rec["programs"] += 1
        rec["small_programs"] += duration < SMALL_S


_gc_start: list[float | None] = [None]


def _on_gc(phase: str, info: dict) -> None:
    if phase == "start":
        _gc_start[0] = time.perf_counter()
    elif _gc_start[0] is not None and _current[0] is not None:
        _records[_current[0]]["gc_s"] += time.perf_counter() - _gc_start[0]


def _cpu() -> tuple[float, float]:
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime, children.ru_utime + children.ru_stime


def pytest_configure(config) -> None:
    import jax.monitoring

    jax.monitoring.register_event_duration_secs_listener(_on_event)
    gc.callbacks.append(_on_gc)


@pytest.hookimpl(wrapper=True)
def pytest_runtest_protocol(item, nextitem):
    """Times the whole protocol of one test: setup, call, teardown."""
    _current[0] = item.nodeid
    wall0, (own0, children0) = time.perf_counter(), _cpu()
    try:
        return (yield)
    finally:
        own, children = _cpu()
        rec = _records[item.nodeid]
        rec["wall_s"] += time.perf_counter() - wall0
        rec["cpu_s"] += own - own0
        rec["subprocess_cpu_s"] += children - children0
        _current[0] = None


def pytest_sessionfinish(session) -> None:
    out = os.environ.get("SUITE_PROFILE_DIR")
    if out and _records:
        os.makedirs(out, exist_ok=True)
        run = os.environ.get("PYTEST_XDIST_TESTRUNUID") or uuid.uuid4().hex  # the workers' common id
        with open(os.path.join(out, f"profile-{run}-{os.getpid()}.json"), "w") as f:
            json.dump(_records, f)


def load(folder: str) -> dict[str, dict[str, float]]:
    """The newest run's records in ``folder``, its workers' merged: test id -> field -> value."""
    runs: dict[str, list[str]] = collections.defaultdict(list)
    for path in glob.glob(os.path.join(folder, "profile-*-*.json")):
        runs[os.path.basename(path).split("-")[1]].append(path)
    if not runs:
        return {}
    newest = max(runs.values(), key=lambda paths: max(os.path.getmtime(p) for p in paths))
    merged: dict[str, dict[str, float]] = {}
    for path in sorted(newest):
        with open(path) as f:
            merged.update(json.load(f))
    return merged


def totals(records: dict[str, dict[str, float]], key=lambda test: "all") -> dict[str, dict[str, float]]:
    """Sums of every field and of each test's ``waiting_s``, grouped by ``key(test id)``."""
    fields = FIELDS + ("waiting_s",)
    out: dict[str, dict[str, float]] = collections.defaultdict(lambda: dict.fromkeys(fields, 0.0))
    for test, rec in records.items():
        row = out[key(test)]
        for field in FIELDS:
            row[field] += rec.get(field, 0.0)
        row["waiting_s"] += waiting_s(rec)
    return dict(out)


def short_name(test_id: str, width: int = 60) -> str:
    """``tests/test_d2c.py::test_x[p]`` -> ``d2c::x[p]``, cut at its end to ``width``."""
    path, _, name = test_id.partition("::")
    base = os.path.basename(path).removeprefix("test_").removesuffix(".py")
    text = f"{base}::{name.removeprefix('test_')}" if name else base
    return text if len(text) <= width else text[: width - 3] + "..."


def waiting_s(rec: dict[str, float]) -> float:
    """A test's wall time in which neither its process nor its children ran: sleeps, wall
    clocks, signals, other processes (on a loaded machine also CPU that others took)."""
    return max(0.0, rec.get("wall_s", 0.0) - rec.get("cpu_s", 0.0) - rec.get("subprocess_cpu_s", 0.0))


# column heads, two lines each, and the fields they show
COLUMNS = (
    ("wall", "s", "wall_s"),
    ("cpu", "s", "cpu_s"),
    ("child", "cpu s", "subprocess_cpu_s"),
    ("compile", "s", "compile_s"),
    ("trace", "s", "trace_s"),
    ("lower", "s", "lower_s"),
    ("programs", "", "programs"),
    ("small", "programs", "small_programs"),
    ("gc", "s", "gc_s"),
    ("waiting", "s", "waiting_s"),
)


def _table(rows: dict[str, dict[str, float]], top: int) -> str:
    lines = [f"{'':60s}" + "".join(f"{c[i]:>10s}" for c in COLUMNS) for i in (0, 1)]
    for name, row in sorted(rows.items(), key=lambda kv: -kv[1]["wall_s"])[:top]:
        cells = (f"{row[f]:10.0f}" if "programs" in f else f"{row[f]:10.1f}" for _, _, f in COLUMNS)
        lines.append(f"{short_name(name):60s}" + "".join(cells))
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folder", help="the SUITE_PROFILE_DIR of a profiled run")
    ap.add_argument("--top", type=int, default=30, help="how many files and tests to list")
    a = ap.parse_args(argv)
    records = load(a.folder)
    if not records:
        ap.error(f"folder: no profile-*.json in {a.folder!r}; record one first (see --help)")
    print(f"{len(records)} tests\n" + _table(totals(records), 1))
    print("\nby file\n" + _table(totals(records, lambda t: t.split("::")[0]), a.top))
    print("\nby test\n" + _table(totals(records, lambda t: t), a.top))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
