"""Helpers shared by the test files."""

from __future__ import annotations

import os
import re


def assert_png(path: str, min_pixels: int = 200) -> None:
    """A real figure: a PNG that decodes, of a plausible size, not one flat colour."""
    import matplotlib.image

    img = matplotlib.image.imread(path)
    assert img.ndim == 3 and min(img.shape[:2]) >= min_pixels, (path, img.shape)
    assert float(img[..., :3].std()) > 0.01, f"{path} is blank"


def as_users_run() -> dict:
    """The environment without the suite's -O0 code generation (conftest.py)."""
    env = dict(os.environ)
    env["XLA_FLAGS"] = re.sub(r"--xla_backend_optimization_level=\S+", "", env.get("XLA_FLAGS", "")).strip()
    if not env["XLA_FLAGS"]:
        del env["XLA_FLAGS"]
    return env
