"""The run lifecycle: every finished stage kept, whatever ends the run."""

import glob
import json
import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
from helpers import assert_png

from experiments import run as cli
from mjx_surrogate import progress
from mjx_surrogate.runs.results import Run, RunFolder, load_run

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# A D2C solve that would run for many minutes: the cost never stops changing by the rules
# (rel_tol = k_tol = 0) and the regularisation grows by 1e-6 per rejected step.
ENDLESS = [
    "smoke_d2c",
    "--solver.max_iter",
    "1000000",
    "--solver.rel_tol",
    "0",
    "--solver.k_tol",
    "0",
    "--solver.mu_factor",
    "1.000001",
    "--experiment.exact-oracle",
    "False",
    "--experiment.progress",
]


def _signal_and_time(proc: subprocess.Popen, sig: int, timeout: float) -> tuple[int, float]:
    """Send ``sig`` to the running ``proc`` and wait for it: (exit status, seconds from the
    signal to the exit); raises if it has not ended within ``timeout``."""
    t_signal = time.time()
    proc.send_signal(sig)
    code = proc.wait(timeout=timeout)
    return code, time.time() - t_signal


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_signal_mid_solve_ends_the_run_interrupted_and_keeps_its_results(tmp_path, sig):
    proc = subprocess.Popen(
        [sys.executable, "-m", "experiments.run", *ENDLESS, "--out", str(tmp_path)],
        cwd=ROOT,
        stderr=subprocess.PIPE,
        stdout=subprocess.PIPE,
    )
    seen = bytearray()

    def reader():
        while chunk := os.read(proc.stderr.fileno(), 4096):
            seen.extend(chunk)

    threading.Thread(target=reader, daemon=True).start()
    try:
        deadline = time.time() + 300
        while time.time() < deadline:  # until the bar shows the solve iterating
            done = [int(n) for n in re.findall(rb"\| *(\d+)/1000000", bytes(seen))]
            if done and max(done) >= 50:
                break
            assert proc.poll() is None, seen.decode(errors="replace")
            time.sleep(0.2)
        code, stop_s = _signal_and_time(proc, sig, timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert code == 130, seen.decode(errors="replace")[-2000:]
    assert stop_s < 60  # prompt: after the current chunk of iterations, then the writing
    assert not glob.glob(str(tmp_path / ".*")), "a .partial folder was left behind"
    (path,) = glob.glob(str(tmp_path / "*smoke_d2c"))
    metrics, arrays = load_run(path)
    assert metrics["status"] == "interrupted"
    assert metrics["stages"]["d2c"]["status"] == "interrupted"
    assert metrics["d2c"]["status"] == "interrupted" and metrics["d2c"]["iterations"] > 0
    assert metrics["d2c"]["cost"] is not None
    assert {"x0", "d2c_U", "d2c_X", "d2c_K", "d2c_cost_history"} <= set(arrays)
    assert "feedback" not in metrics["stages"]  # nothing ran after the stop
    assert b"Traceback" not in seen


@pytest.mark.slow
def test_failed_figure_keeps_the_solve_and_is_reported(tmp_path, monkeypatch):
    from mjx_surrogate.runs import plots

    def broken(*args, **kwargs):
        raise RuntimeError("a plotting bug")

    monkeypatch.setattr(plots, "cost_history", broken)
    code = cli.main(["smoke_d2c", "--out", str(tmp_path), "--experiment.exact-oracle", "False"])
    (path,) = glob.glob(str(tmp_path / "*smoke_d2c"))
    metrics, arrays = load_run(path)
    assert code == 0 and metrics["status"] == "converged"
    assert metrics["figures"]["cost_history.png"] == {
        "status": "failed",
        "error": "RuntimeError: a plotting bug",
    }
    assert metrics["figures"]["feedback_noise.png"] == "written"
    assert_png(os.path.join(path, "feedback_noise.png"))
    assert not os.path.exists(os.path.join(path, "cost_history.png"))
    assert {"d2c_U", "d2c_X", "feedback_closed_costs"} <= set(arrays)


def test_failed_stage_keeps_the_earlier_stages(tmp_path, monkeypatch, capsys):
    import experiments.d2c_study as study

    def broken(*args, **kwargs):
        raise FloatingPointError("feedback exploded")

    monkeypatch.setattr(study, "evaluate_feedback", broken)
    code = cli.main(["smoke_d2c", "--out", str(tmp_path), "--experiment.exact-oracle", "False"])
    (path,) = glob.glob(str(tmp_path / "*smoke_d2c"))
    metrics, arrays = load_run(path)
    assert code == 1 and metrics["status"] == "failed"
    assert metrics["error"] == "FloatingPointError: feedback exploded"
    assert metrics["stages"]["d2c"]["status"] == "done"
    assert metrics["stages"]["feedback"]["status"] == "failed"
    assert metrics["d2c"]["status"] == "converged" and "d2c_U" in arrays
    assert "[failed]" in capsys.readouterr().out


def test_folder_of_a_killed_run_is_recovered_by_the_next_run(tmp_path):
    dead = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True
    ).stdout.strip()
    killed = RunFolder(str(tmp_path), "killed")
    record = Run(killed)
    record.stage("first", lambda: ({"cost": 1.5}, {"U": np.ones(3)}))
    alive = RunFolder(str(tmp_path), "alive")  # a live run's folder is left alone
    killed.write_json(".owner", {"pid": int(dead), "host": socket.gethostname()})
    nxt = RunFolder(str(tmp_path), "next")
    assert nxt.recovered == [killed.final_path]
    metrics, arrays = load_run(killed.final_path)
    assert metrics["status"] == "killed" and metrics["first"] == {"cost": 1.5}
    np.testing.assert_array_equal(arrays["U"], np.ones(3))
    assert os.path.isdir(alive.path) and alive.path.endswith(".partial")


def test_resume_reuses_finished_stages_only(tmp_path):
    first = Run(RunFolder(str(tmp_path), "a"))
    first.stage("done", lambda: ({"x": 1}, {"a": np.arange(3)}))
    with pytest.raises(ZeroDivisionError):
        first.stage("broken", lambda: 1 / 0)
    path = first.finish("failed", ZeroDivisionError("x"))

    calls = []
    again = Run(RunFolder(str(tmp_path), "b"), resume_from=path)
    m, a = again.stage("done", lambda: calls.append("done") or ({"x": 2}, {"a": np.zeros(3)}))
    assert m == {"x": 1} and np.array_equal(a["a"], np.arange(3)) and calls == []
    m, _ = again.stage("broken", lambda: calls.append("broken") or ({"y": 3}, {}))
    assert m == {"y": 3} and calls == ["broken"]
    assert again.metrics["stages"]["done"]["resumed"] is True


def test_a_stage_that_finishes_after_a_stop_request_is_done_and_the_next_never_starts(tmp_path):
    """Nor is its figure drawn: drawing one (the humanoid's trajectories) polls for no stop
    and outlasted the watchdog's grace, whose exit then misreported the kept stage."""
    from mjx_surrogate.runs.results import Interrupted

    record = Run(RunFolder(str(tmp_path), "s"))
    progress.clear_stop()
    calls = []
    try:
        m, _ = record.stage("long", lambda: progress.request_stop() or ({"it": 3}, {"U": np.ones(2)}))
        assert m == {"it": 3}
        assert not record.figure("long.png", lambda: calls.append("drawn"))
        with pytest.raises(Interrupted):
            record.stage("next", lambda: calls.append(1) or ({}, {}))
    finally:
        progress.clear_stop()
    assert record.metrics["stages"]["long"]["status"] == "done" and calls == []
    assert record.metrics["figures"]["long.png"]["status"] == "skipped"
    assert json.load(open(os.path.join(record.folder.path, "metrics.json")))["long"] == {"it": 3}


def test_a_stage_whose_solve_was_cut_short_is_interrupted(tmp_path):
    from mjx_surrogate.runs.results import Interrupted

    record = Run(RunFolder(str(tmp_path), "s"))
    with pytest.raises(Interrupted):
        record.stage("solve", lambda: ({"status": "interrupted", "cost": 2.0}, {"U": np.ones(2)}))
    assert record.metrics["stages"]["solve"]["status"] == "interrupted"
    assert record.metrics["solve"]["cost"] == 2.0


# A run whose second stage never polls for a stop (time.sleep stands for a compile or a
# long jitted call: the signal handler runs and the sleep resumes).
STUCK = """
import sys, time
import numpy as np
from experiments import run as cli
from mjx_surrogate.runs.experiment_kinds import ExperimentKind, register_experiment

def kind(res, record, key):
    record.stage("first", lambda: ({"x": 1.0}, {"a": np.arange(3.0)}))
    record.figure("first.png", lambda: __import__("mjx_surrogate.runs.plots", fromlist=["x"]).cost_history(
        {"a": np.array([3.0, 2.0, 1.0])}, "first"))
    print("READY", flush=True)
    record.stage("stuck", lambda: (time.sleep(600), ({}, {}))[1])
    return "completed"

register_experiment("stuck", ExperimentKind(kind))
args = ["--experiment.kind", "stuck", "--experiment.no-progress", "--out", sys.argv[1]]
sys.exit(cli.main(["smoke_d2c", *args]))
"""


@pytest.mark.parametrize(
    "sig,reader_gone",
    [(signal.SIGTERM, False), (signal.SIGINT, False), (signal.SIGTERM, True)],
    ids=["SIGTERM", "SIGINT", "SIGTERM-output-closed"],
)
@pytest.mark.slow
def test_a_stage_that_polls_for_no_stop_still_ends_within_5_s(tmp_path, sig, reader_gone):
    proc = subprocess.Popen(
        [sys.executable, "-c", STUCK, str(tmp_path)],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env={**os.environ, "MPLBACKEND": "Agg"},
    )
    try:
        assert proc.stdout.readline().strip() == b"READY", proc.stderr.read().decode()[-2000:]
        if reader_gone:  # as when the pipe the run printed into was closed
            proc.stdout.close()
            proc.stderr.close()
        time.sleep(0.5)
        code, stop_s = _signal_and_time(proc, sig, timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    out, err = ("", "") if reader_gone else (proc.stdout.read().decode(), proc.stderr.read().decode())
    assert code == 130, err[-2000:]
    assert stop_s < 5.0, stop_s
    assert reader_gone or ("Traceback" not in err and "[interrupted]" in out)
    assert not glob.glob(str(tmp_path / ".*.partial"))
    (path,) = glob.glob(str(tmp_path / "*smoke_d2c"))
    metrics, arrays = load_run(path)
    assert metrics["status"] == "interrupted" and "'stuck' did not end" in metrics["error"]
    assert metrics["stages"]["first"]["status"] == "done" and metrics["first"] == {"x": 1.0}
    assert metrics["stages"]["stuck"]["status"] == "interrupted"
    np.testing.assert_array_equal(arrays["a"], np.arange(3.0))
    assert metrics["figures"]["first.png"] == "written"
    assert_png(os.path.join(path, "first.png"))


@pytest.mark.parametrize("current", ["slow", None], ids=["during-a-stage", "between-stages"])
def test_the_watchdogs_exit_says_what_it_dropped_and_what_is_kept(tmp_path, monkeypatch, capsys, current):
    """The hard exit names the stage whose work it dropped; between stages nothing is dropped
    and it says that every finished stage is kept (not that partial work was lost)."""
    record = Run(RunFolder(str(tmp_path), "s"))
    record.stage("done", lambda: ({"x": 1.0}, {}))
    record.current = current
    exits = []
    monkeypatch.setattr(cli.os, "_exit", exits.append)
    cli._stop_now(record)
    error = json.load(open(os.path.join(record.folder.path, "metrics.json")))["error"]
    assert exits == [130] and record.metrics["stages"]["done"]["status"] == "done"
    if current:
        assert "stage 'slow' did not end" in error and "partial work was not kept" in error
        assert record.metrics["stages"]["slow"]["status"] == "interrupted"
    else:
        assert "partial work" not in error and "every stage it finished is kept" in error
    assert error in capsys.readouterr().out


def test_a_stop_between_the_steps_of_a_stage_ends_it_interrupted(tmp_path):
    from mjx_surrogate.runs.results import Interrupted

    record = Run(RunFolder(str(tmp_path), "s"))
    ran = []

    def compute():
        with progress.steps("steps", 3, display=False) as meter:
            for label in ("one", "two", "three"):
                meter.advance(label)
                ran.append(label)
                progress.request_stop()
        return {"x": 1}, {}

    progress.clear_stop()
    try:
        with pytest.raises(Interrupted):
            record.stage("s", compute)
    finally:
        progress.clear_stop()
    assert ran == ["one"] and record.metrics["stages"]["s"]["status"] == "interrupted"
    assert "s" not in record.metrics  # its partial work is not kept as a result


@pytest.mark.slow
def test_a_run_stopped_after_its_d2c_stage_keeps_that_stages_figures(tmp_path, monkeypatch):
    import experiments.d2c_study as study

    original = study.chunked.solve_exact

    def stop_then_solve(*args, **kwargs):
        progress.request_stop()  # as a signal arriving while the oracle compiles
        return original(*args, **kwargs)

    monkeypatch.setattr(study.chunked, "solve_exact", stop_then_solve)
    # The stop is to be seen by the oracle's first chunk (the soft path), however long its
    # compile takes on a loaded machine: the watchdog's hard exit, tested above in a
    # subprocess, would otherwise end this test's process after STOP_GRACE_S.
    monkeypatch.setattr(cli, "_stop_now", lambda record: None)
    progress.clear_stop()
    try:
        code = cli.main(["smoke_d2c", "--out", str(tmp_path), "--experiment.no-progress"])
    finally:
        progress.clear_stop()
    (path,) = glob.glob(str(tmp_path / "*smoke_d2c"))
    metrics, _ = load_run(path)
    assert code == 130 and metrics["status"] == "interrupted"
    assert metrics["stages"]["d2c"]["status"] == "done"
    assert metrics["stages"]["exact"]["status"] == "interrupted"
    for name in ("cost_vs_simulations.png", "trajectory_evolution.png"):
        assert metrics["figures"][name] == "written"
        assert_png(os.path.join(path, name))
    assert "feedback" not in metrics["stages"]
