"""benchmarks/suite_profile.py: a profiled pytest run records each test's compiles and CPU."""

import os
import subprocess
import sys
import textwrap

import pytest

from benchmarks import suite_profile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

TESTS = """
import gc, subprocess, sys

import jax
import jax.numpy as jnp
import numpy as np


def test_two_new_programs():
    f = jax.jit(lambda x: jnp.sin(x) * 2.0)
    assert float(f(np.float32(0.0))) == 0.0
    assert f(np.zeros(3, np.float32)).shape == (3,)  # a second shape: a second program


def test_a_busy_child_and_the_collector():
    for _ in range(20):  # cycles of objects only the collector frees, and 20 full collections
        cycles = [[] for _ in range(100_000)]
        for c in cycles:
            c.append(c)
        del cycles
        gc.collect()
    code = "s = 0\\nfor i in range(3_000_000): s += i"
    subprocess.run([sys.executable, "-c", code], check=True)
"""


@pytest.mark.slow
def test_a_profiled_run_counts_each_tests_programs_and_its_childs_cpu(tmp_path):
    (tmp_path / "test_tiny.py").write_text(textwrap.dedent(TESTS))
    out = tmp_path / "profile"
    env = dict(os.environ, SUITE_PROFILE_DIR=str(out), PYTHONPATH=ROOT)
    for name in ("PYTEST_XDIST_TESTRUNUID", "PYTEST_ADDOPTS"):  # this run's, when profiled or under xdist
        env.pop(name, None)
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "benchmarks.suite_profile", "-p", "no:cacheprovider"]
    done = subprocess.run(cmd + [str(tmp_path)], cwd=tmp_path, env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stdout[-2000:]
    records = suite_profile.load(str(out))
    programs = records["test_tiny.py::test_two_new_programs"]
    child = records["test_tiny.py::test_a_busy_child_and_the_collector"]
    assert programs["programs"] == 2 and programs["compile_s"] > 0 and programs["trace_s"] > 0
    assert programs["wall_s"] >= programs["compile_s"]
    assert child["programs"] == 0 and child["subprocess_cpu_s"] > 0.05, child
    assert child["gc_s"] > 0.05 and child["gc_s"] > 10 * programs["gc_s"], (child, programs)
    everything = suite_profile.totals(records)["all"]
    assert everything["programs"] == 2 and everything["wall_s"] == pytest.approx(
        programs["wall_s"] + child["wall_s"]
    )
    assert suite_profile.main([str(out), "--top", "3"]) == 0
    # a second run into the same folder: the summary reads it alone
    again = subprocess.run(cmd + ["-k", "child", str(tmp_path)], cwd=tmp_path, env=env, capture_output=True)
    assert again.returncode == 0 and len(list(out.iterdir())) == 2
    assert list(suite_profile.load(str(out))) == ["test_tiny.py::test_a_busy_child_and_the_collector"]
    with pytest.raises(SystemExit) as exc:
        suite_profile.main([str(tmp_path / "nothing")])
    assert exc.value.code == 2


def test_the_summary_names_tests_short_and_sums_each_tests_waiting(capsys, tmp_path):
    """A test that waited (a sleep: wall over its CPU) keeps its waiting in its file's row,
    whatever a busier test beside it (CPU over wall: threads) does; names lose their
    ``tests/test_`` and are cut at their end."""
    import json

    blank = dict.fromkeys(suite_profile.FIELDS, 0.0)
    records = {
        "tests/test_a.py::test_sleeps": {**blank, "wall_s": 10.0, "cpu_s": 2.0, "subprocess_cpu_s": 1.0},
        "tests/test_a.py::test_threads": {**blank, "wall_s": 4.0, "cpu_s": 9.0},
        "tests/test_b.py::test_" + "x" * 80: {**blank, "wall_s": 1.0, "cpu_s": 1.0},
    }
    by_file = suite_profile.totals(records, lambda t: t.split("::")[0])
    assert by_file["tests/test_a.py"]["waiting_s"] == 7.0 and by_file["tests/test_b.py"]["waiting_s"] == 0.0
    assert suite_profile.short_name("tests/test_d2c.py::test_x[central]") == "d2c::x[central]"
    assert suite_profile.short_name("tests/test_d2c.py") == "d2c"
    long = suite_profile.short_name("tests/test_b.py::test_" + "x" * 80)
    assert len(long) == 60 and long.startswith("b::xxx") and long.endswith("...")
    (tmp_path / "profile-run-1.json").write_text(json.dumps(records))
    assert suite_profile.main([str(tmp_path), "--top", "5"]) == 0
    out = capsys.readouterr().out
    row = next(line for line in out.splitlines() if line.startswith("a::sleeps"))
    assert row.split()[-1] == "7.0"  # waiting: 10 s of wall, 3 s of CPU
