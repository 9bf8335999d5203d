"""mjx_surrogate/runs/video.py: frame rates, tiling, and a renderer without a GL context."""

import os

import mujoco
import numpy as np
import pytest

from mjx_surrogate.runs import video
from mjx_surrogate.systems import make_system


def test_frame_rate_plays_control_steps_in_real_time():
    assert video.frame_rate(0.1) == (pytest.approx(10.0), 1)
    fps, stride = video.frame_rate(0.005)  # 200 steps a second: every 4th, 50 frames a second
    assert stride == 4 and fps == pytest.approx(50.0)


def test_tile_puts_clips_side_by_side_and_holds_the_shorter_ones_last_frame():
    a = np.zeros((3, 2, 4, 3), np.uint8)
    b = np.stack([np.full((2, 4, 3), i, np.uint8) for i in (7, 9)])
    t = video.tile([a, b])
    assert t.shape == (3, 2, 8, 3)
    assert np.all(t[:, :, 4:][2] == 9) and np.all(t[:, :, :4] == 0)


def test_a_label_is_written_on_a_dark_band_at_the_top_of_every_frame():
    frames = np.full((4, 60, 120, 3), 200, np.uint8)
    frames[:, 30:] = np.arange(4)[:, None, None, None]  # the rest of the picture, per frame
    out = video.label(frames, "D2C-MPC")
    band = out[:, : video.LABEL_HEIGHT]
    assert np.all(out[:, video.LABEL_HEIGHT :] == frames[:, video.LABEL_HEIGHT :])
    assert np.all(band == band[0]) and band.mean() < 80  # the same band on every frame, dark
    assert (band[0].min(-1) > 200).sum() > 30  # and white text on it
    assert not np.array_equal(band[0], video.label(frames, "MPPI")[0, : video.LABEL_HEIGHT])


def test_the_renderer_child_imports_neither_the_package_nor_jax():
    """The child runs this module's file as a script: MuJoCo, NumPy, imageio and PIL only
    (the package's import, which starts JAX, took 2.1 s of every video)."""
    import subprocess
    import sys

    cmd = video.child_command(["--help"])
    assert cmd[0] == sys.executable and cmd[3] == os.path.abspath(video.__file__)
    done = subprocess.run([cmd[0], "-X", "importtime", *cmd[1:]], capture_output=True, text=True)
    assert done.returncode == 0 and "keys" in done.stdout, done.stderr[-2000:]
    imported = {ln.split("|")[-1].strip() for ln in done.stderr.splitlines() if ln.startswith("import time:")}
    assert "argparse" in imported and not {"jax", "mjx_surrogate"} & imported, sorted(imported)[:50]


@pytest.mark.slow
def test_without_a_gl_context_the_reason_comes_back_in_one_line_and_nothing_is_written(tmp_path, monkeypatch):
    model = make_system("pendulum", "native").mj_model
    mujoco.mj_saveModel(model, str(tmp_path / "m.mjb"), None)
    np.savez(tmp_path / "a.npz", X=np.zeros((3, 2)))
    monkeypatch.setenv("MUJOCO_GL", "glfw")  # needs a display; there is none
    monkeypatch.delenv("DISPLAY", raising=False)
    reason = video.write_video(
        str(tmp_path / "m.mjb"), str(tmp_path / "a.npz"), ["X"], str(tmp_path / "v.mp4"), 0.1
    )
    assert reason and "\n" not in reason
    assert not (tmp_path / "v.mp4").exists()


@pytest.mark.slow
def test_a_d2c_run_writes_the_video_of_its_optimum(tmp_path):
    """The main job's kind keeps its optimum as d2c_X: its video has one frame per state."""
    import json

    import imageio.v2 as imageio

    from experiments import run as cli

    assert cli.main(["smoke_d2c", "--experiment.video", "--out", str(tmp_path)]) == 0
    (path,) = tmp_path.iterdir()
    m = json.loads((path / "metrics.json").read_text())
    assert m["videos"]["optimum.mp4"] == {
        "status": "written",
        "trajectories": ["d2c_X"],
        "still": "optimum_still.png",
    }
    frames = imageio.mimread(str(path / "optimum.mp4"))
    assert len(frames) == len(np.load(path / "arrays.npz")["d2c_X"])
    still = imageio.imread(path / "optimum_still.png")  # the middle frame, up to the codec's loss
    dist = [np.abs(still.astype(float) - f).mean() for f in frames]
    assert abs(int(np.argmin(dist)) - len(frames) // 2) <= 1 and still.std() > 2
    assert "data:video/mp4;base64," in (path / "report.html").read_text()
