"""Videos of state trajectories on MuJoCo models, rendered headless.

Rendering runs in a child process (this file run as a script, :func:`child_command`) whose
environment sets ``MUJOCO_GL=egl`` (unless the caller chose a backend): MuJoCo picks its GL
backend when it is imported, and a GL failure or crash there cannot take the run with it.
The child imports MuJoCo, NumPy, imageio and PIL only, not the package (which would import
JAX: 2.4 s a video, against 0.3 s). Frames:
x = [qpos, qvel, act] -> qpos set, ``mj_forward``, one frame per control step, from a free
camera on the model's centre with a brighter headlight (models without lights stay
visible); several trajectories are tiled side by side, each named on a band at its top.
Written as H.264 MP4 by imageio-ffmpeg, played in real time (one frame per control step,
at most 60 per second: longer trajectories keep every k-th frame).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys

import numpy as np

WIDTH, HEIGHT = 320, 240
MAX_FPS = 60
LABEL_HEIGHT = 18  # pixels of the band that names a clip


def frame_rate(dt: float) -> tuple[float, int]:
    """(frames per second, stride) that play control steps of ``dt`` seconds in real time."""
    stride = max(1, math.ceil(1.0 / (dt * MAX_FPS)))
    return 1.0 / (dt * stride), stride


def render(model, X: np.ndarray, width: int = WIDTH, height: int = HEIGHT) -> np.ndarray:
    """uint8 frames [N, height, width, 3] of the states X [N, nx] of ``model`` (an MjModel)."""
    import copy

    import mujoco

    m = copy.deepcopy(model)
    m.vis.headlight.ambient[:] = 0.35
    m.vis.headlight.diffuse[:] = 0.7
    m.vis.global_.offwidth, m.vis.global_.offheight = (
        max(width, m.vis.global_.offwidth),
        max(height, m.vis.global_.offheight),
    )
    d = mujoco.MjData(m)
    cam = mujoco.MjvCamera()
    mujoco.mjv_defaultFreeCamera(m, cam)
    cam.elevation, cam.distance = -20.0, 2.0 * m.stat.extent
    frames = np.empty((len(X), height, width, 3), np.uint8)
    with mujoco.Renderer(m, height, width) as r:
        for i, x in enumerate(X):
            d.qpos[:] = x[: m.nq]
            mujoco.mj_forward(m, d)
            r.update_scene(d, cam)
            frames[i] = r.render()
    return frames


def label(frames: np.ndarray, text: str) -> np.ndarray:
    """The clip frames [N, H, W, 3] with ``text`` written white on a dark band at the top."""
    from PIL import Image, ImageDraw, ImageFont

    band = Image.fromarray(np.ascontiguousarray(frames[0, :LABEL_HEIGHT]))
    draw = ImageDraw.Draw(band)
    draw.rectangle((0, 0, band.width, LABEL_HEIGHT), fill=(20, 20, 20))
    draw.text((4, 2), text, fill=(255, 255, 255), font=ImageFont.load_default(size=LABEL_HEIGHT - 5))
    out = frames.copy()
    out[:, :LABEL_HEIGHT] = np.asarray(band)
    return out


def tile(clips: list[np.ndarray]) -> np.ndarray:
    """Clips [N_i, H, W, 3] side by side; shorter ones hold their last frame."""
    n = max(len(c) for c in clips)
    padded = [np.concatenate([c, np.repeat(c[-1:], n - len(c), axis=0)]) for c in clips]
    return np.concatenate(padded, axis=2)


def write_mp4(path: str, frames: np.ndarray, fps: float) -> None:
    import imageio.v2 as imageio

    with imageio.get_writer(path, fps=fps, codec="libx264", quality=7, macro_block_size=16) as w:
        for f in frames:
            w.append_data(f)


def still_path(video: str) -> str:
    """The PNG beside a video that holds its middle frame (``optimum.mp4`` -> ``optimum_still.png``)."""
    return os.path.splitext(video)[0] + "_still.png"


# runs a file as __main__ without putting its folder first on sys.path (runpy.run_path
# leaves sys.path alone for a plain file; Python 3.10 has no ``-P``)
_RUN_FILE = "import runpy, sys; sys.argv = sys.argv[1:]; runpy.run_path(sys.argv[0], run_name='__main__')"


def child_command(args: list[str]) -> list[str]:
    """The renderer's command line: this file run as a script with ``args``."""
    return [sys.executable, "-c", _RUN_FILE, os.path.abspath(__file__), *args]


def write_video(
    model_path: str,
    arrays_path: str,
    keys: list[str],
    out: str,
    dt: float,
    timeout_s: float = 300,
    labels: list[str] | None = None,
) -> str | None:
    """Render the trajectories ``keys`` of the ``.npz`` at ``arrays_path`` (each [N+1, nx],
    or [E, N+1, nx]: its first) on the compiled model at ``model_path`` into ``out``, in a
    child process, with its middle frame as :func:`still_path`; ``labels``, one per key,
    are written on the clips. None when written, else one line saying why not."""
    env = dict(os.environ)
    env.setdefault("MUJOCO_GL", "egl")
    cmd = child_command([model_path, arrays_path, out, str(dt), *keys])
    if labels is not None:
        cmd += ["--labels", json.dumps(list(labels))]
    try:
        p = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=timeout_s)
    except subprocess.TimeoutExpired:
        return f"rendering took over {timeout_s:g} s"
    if p.returncode != 0:
        lines = [line for line in (p.stderr or "").strip().splitlines() if line.strip()]
        return lines[-1] if lines else f"the renderer exited with status {p.returncode}"
    return None


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="Render trajectories of a MuJoCo model to an MP4.")
    ap.add_argument("model")
    ap.add_argument("arrays")
    ap.add_argument("out")
    ap.add_argument("dt", type=float)
    ap.add_argument("keys", nargs="+")
    ap.add_argument("--labels", default=None, help="a JSON list of one label per key")
    a = ap.parse_args(argv)
    labels = json.loads(a.labels) if a.labels else [None] * len(a.keys)
    import mujoco

    model = mujoco.MjModel.from_binary_path(a.model)
    arrays = np.load(a.arrays)
    fps, stride = frame_rate(a.dt)
    clips = []
    for k, text in zip(a.keys, labels):
        X = np.asarray(arrays[k])
        X = X[0] if X.ndim == 3 else X
        clip = render(model, X[::stride])
        clips.append(clip if text is None else label(clip, text))
    frames = tile(clips)
    try:
        write_mp4(a.out, frames, fps)
        import imageio.v2 as imageio

        imageio.imwrite(still_path(a.out), frames[len(frames) // 2])
    except Exception:
        for p in (a.out, still_path(a.out)):
            if os.path.exists(p):
                os.remove(p)
        raise
    return 0


if __name__ == "__main__":
    sys.exit(main())
