"""Run folders under a hostile file system: a full disk, an output folder made read-only
mid-run, many processes starting into one folder, the umask."""

from __future__ import annotations

import contextlib
import glob
import json
import os
import shutil
import stat
import subprocess
import sys
import uuid

import pytest

from experiments import run as cli
from mjx_surrogate.runs import results
from mjx_surrogate.runs.results import Run, RunFolder, load_run, recover_stale

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SMOKE = ["smoke_d2c", "--experiment.exact-oracle", "False", "--experiment.no-progress"]


@contextlib.contextmanager
def small_tmpfs(kib: int):
    """A tmpfs of ``kib`` KiB (root only, where mounts are allowed), unmounted after."""
    path = f"/tmp/mjx_surrogate_tmpfs_{uuid.uuid4().hex[:8]}"
    os.makedirs(path)
    try:
        if os.geteuid() != 0 or shutil.which("mount") is None:
            pytest.skip("mounting a tmpfs needs root")
        done = subprocess.run(
            ["mount", "-t", "tmpfs", "-o", f"size={kib}k", "tmpfs", path], capture_output=True
        )
        if done.returncode != 0:
            pytest.skip(f"cannot mount a tmpfs here: {done.stderr.decode().strip()}")
        try:
            yield path
        finally:
            subprocess.run(["umount", "-l", path], check=False)
    finally:
        with contextlib.suppress(OSError):
            os.rmdir(path)


def fill(path: str, leave_kib: int) -> None:
    """Fill the file system of ``path`` up to ``leave_kib`` KiB free."""
    filler = os.path.join(path, "filler")
    fd = os.open(filler, os.O_WRONLY | os.O_CREAT, 0o644)
    try:
        with contextlib.suppress(OSError):
            while True:
                os.write(fd, b"\0" * 4096)
    finally:
        os.close(fd)
    os.truncate(filler, max(0, os.path.getsize(filler) - leave_kib * 1024))
    assert abs(shutil.disk_usage(path).free - leave_kib * 1024) <= 8 * 1024


def _one_error_line(capsys) -> str:
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(err) == 1, err
    return err[0]


@pytest.mark.parametrize("free_kib", [56, 0])  # 56: the inputs and the first stages fit, a figure does not
def test_full_disk_ends_failed_with_one_line_and_is_never_relabelled(free_kib, capsys):
    with small_tmpfs(2048) as fs:
        out = os.path.join(fs, "runs")
        os.makedirs(out)
        fill(fs, free_kib)
        code = cli.main([*SMOKE, "--out", out])
        line = _one_error_line(capsys)
        assert code == 1
        assert line.startswith("error: ") and "[Errno 28]" in line and out in line, line
        assert not glob.glob(os.path.join(out, ".*.partial")), "left .partial"
        folders = glob.glob(os.path.join(out, "*_smoke_d2c"))
        if free_kib == 0:  # not even the owner record fits: no folder, said so
            assert folders == [] and "no run folder could be made" in line
            return
        (path,) = folders
        assert path in line
        metrics, arrays = load_run(path)
        assert metrics["status"] == "failed" and "No space left on device" in metrics["error"]
        assert metrics["stages"]["d2c"]["status"] == "done" and "d2c_U" in arrays
        assert recover_stale(out) == [] and load_run(path)[0]["status"] == "failed"


def test_a_stage_whose_arrays_the_disk_refused_says_so(tmp_path, monkeypatch):
    """The stage finished, its arrays did not reach arrays.npz: metrics.json keeps the stage
    and names the arrays it lost (a resume recomputes such a stage)."""
    folder = RunFolder(str(tmp_path), "r")
    record = Run(folder)
    record.stage("a", lambda: ({"x": 1}, {"a_X": [1.0]}))
    write_arrays = folder.write_arrays

    def refuse(name, arrays):
        if "b_X" in arrays:
            raise results.WriteError(os.path.join(folder.path, name), OSError(28, "No space left on device"))
        return write_arrays(name, arrays)

    monkeypatch.setattr(folder, "write_arrays", refuse)
    with pytest.raises(results.WriteError):
        record.stage("b", lambda: ({"y": 2}, {"b_X": [2.0]}))
    with pytest.raises(results.WriteError):
        record.finish("failed")
    (path,) = glob.glob(str(tmp_path / "*_r"))
    metrics, arrays = load_run(path)
    assert metrics["stages"]["b"]["arrays_not_written"] == ["b_X"] and "b_X" not in arrays
    assert "arrays_not_written" not in metrics["stages"]["a"] and "a_X" in arrays


def test_out_dir_made_immutable_mid_run_fails_and_keeps_its_cause(tmp_path, monkeypatch, capsys):
    if shutil.which("chattr") is None or os.geteuid() != 0:
        pytest.skip("needs chattr as root")
    import experiments.d2c_study as study

    out = tmp_path / "runs"
    out.mkdir()
    original = study.evaluate_feedback

    def freeze_then_evaluate(*args, **kwargs):
        if subprocess.run(["chattr", "+i", str(out)], capture_output=True).returncode:
            pytest.skip("chattr +i is not supported on this file system")
        return original(*args, **kwargs)

    monkeypatch.setattr(study, "evaluate_feedback", freeze_then_evaluate)
    try:
        code = cli.main([*SMOKE, "--out", str(out)])
    finally:
        subprocess.run(["chattr", "-i", str(out)], check=False)
    line = _one_error_line(capsys)
    assert code == 1 and "Operation not permitted" in line and str(out) in line, line
    (partial,) = glob.glob(str(out / ".*.partial"))
    metrics = json.load(open(os.path.join(partial, "metrics.json")))
    assert metrics["status"] == "failed" and "Operation not permitted" in metrics["error"]
    assert metrics["stages"]["feedback"]["status"] == "done"
    # A later run into the same folder gives it its name and keeps its status.
    later = RunFolder(str(out), "later")
    (recovered,) = later.recovered
    metrics, _ = load_run(recovered)
    assert metrics["status"] == "failed" and "Operation not permitted" in metrics["error"]
    assert not os.path.exists(os.path.join(recovered, ".owner"))


STORM = """
import sys
from mjx_surrogate.runs.results import Run, RunFolder
out, tag, n = sys.argv[1], sys.argv[2], int(sys.argv[3])
for i in range(n):
    record = Run(RunFolder(out, tag))
    record.stage("only", lambda: ({"i": i}, {}))
    record.finish("completed")
"""


@pytest.mark.slow
def test_many_processes_into_one_out_dir_never_relabel_a_live_run(tmp_path):
    n_proc, n_runs = 4, 30
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", STORM, str(tmp_path), f"p{k}", str(n_runs)],
            cwd=ROOT,
            stderr=subprocess.PIPE,
        )
        for k in range(n_proc)
    ]
    errors = [p.communicate(timeout=300)[1].decode() for p in procs]
    assert all(p.returncode == 0 for p in procs), errors
    folders = [p for p in glob.glob(str(tmp_path / "*")) if os.path.isdir(p)]
    assert len(folders) == n_proc * n_runs
    statuses = {load_run(p)[0]["status"] for p in folders}
    assert statuses == {"completed"}
    assert not glob.glob(str(tmp_path / ".*.partial"))
    assert not [p for p in folders if os.path.exists(os.path.join(p, ".owner"))]


@pytest.mark.parametrize("mask", [0o022, 0o077, 0o002])
def test_result_files_follow_the_umask(tmp_path, mask):
    old = os.umask(mask)
    try:
        record = Run(RunFolder(str(tmp_path), "u"))
        record.stage("s", lambda: ({"x": 1}, {"a": [1.0]}))
        path = record.finish("completed")
    finally:
        os.umask(old)
    for name in ("metrics.json", "arrays.npz"):
        mode = stat.S_IMODE(os.stat(os.path.join(path, name)).st_mode)
        assert mode == 0o666 & ~mask, (name, oct(mode))
    assert stat.S_IMODE(os.stat(path).st_mode) == 0o777 & ~mask


def test_a_folder_left_without_an_end_is_killed_and_its_owner_file_removed(tmp_path):
    folder = RunFolder(str(tmp_path), "dead")
    folder.write_json(".owner", {"pid": 2**22 + 12345, "host": results.socket.gethostname()})
    Run(folder).stage("s", lambda: ({"x": 1}, {}))
    (path,) = recover_stale(str(tmp_path))
    metrics, _ = load_run(path)
    assert metrics["status"] == "killed" and metrics["s"] == {"x": 1}
    assert not os.path.exists(os.path.join(path, ".owner"))


def test_a_replayed_run_is_named_after_its_run():
    assert cli.run_name("runs/20261125-093000_smoke_d2c/config.json") == "smoke_d2c_replay"
    assert cli.run_name("runs/20261125-093000_smoke_d2c_2/config.json") == "smoke_d2c_2_replay"
    assert cli.run_name("my_sweep.json") == "my_sweep"
    assert cli.run_name("cartpole_d2c") == "cartpole_d2c"
