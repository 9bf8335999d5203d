"""Run folders: one new folder per run, every file written atomically.

A run is assembled in ``<out_dir>/.<name>.partial`` and renamed to ``<out_dir>/<name>``
when it is closed, whether it finished, diverged or failed (``metrics.json`` says which),
so a folder under its final name is always complete, and an existing folder is never
overwritten. Schema: docs/results.md.
"""

from __future__ import annotations

import datetime
import io
import json
import os
import platform
import sys
import tempfile
from importlib import metadata
from typing import Any

import numpy as np


def versions() -> dict[str, str]:
    """Versions of python and the numerical stack, for the run folder."""
    out = {"python": sys.version.split()[0], "platform": platform.platform()}
    for pkg in ("jax", "jaxlib", "mujoco", "mujoco-mjx", "flax", "optax", "numpy", "mjx_surrogate"):
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            out[pkg] = "not installed"
    out["XLA_FLAGS"] = os.environ.get("XLA_FLAGS", "")
    return out


def _atomic_write(path: str, data: bytes) -> None:
    folder = os.path.dirname(path)
    fd, tmp = tempfile.mkstemp(dir=folder, prefix=".tmp-")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if hasattr(obj, "tolist"):
        return _jsonable(obj.tolist())
    if isinstance(obj, float) and not np.isfinite(obj):
        return None if np.isnan(obj) else (1e308 if obj > 0 else -1e308)
    return obj


class RunFolder:
    """A run's output folder. Use as a context manager; files appear under the final
    name only when the run is closed."""

    def __init__(self, out_dir: str, name: str):
        os.makedirs(out_dir, exist_ok=True)
        stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
        base = f"{stamp}_{name}"
        k = 0
        while True:
            final = os.path.join(out_dir, base if k == 0 else f"{base}_{k}")
            partial = os.path.join(out_dir, "." + os.path.basename(final) + ".partial")
            if not os.path.exists(final) and not os.path.exists(partial):
                try:
                    os.makedirs(partial)
                    break
                except FileExistsError:
                    pass
            k += 1
        self.final_path = final
        self.path = partial
        self.closed = False

    def write_text(self, name: str, text: str) -> str:
        path = os.path.join(self.path, name)
        _atomic_write(path, text.encode())
        return path

    def write_json(self, name: str, obj: Any) -> str:
        return self.write_text(name, json.dumps(_jsonable(obj), indent=2, allow_nan=False) + "\n")

    def write_arrays(self, name: str, arrays: dict[str, Any]) -> str:
        buf = io.BytesIO()
        np.savez_compressed(buf, **{k: np.asarray(v) for k, v in arrays.items()})
        path = os.path.join(self.path, name)
        _atomic_write(path, buf.getvalue())
        return path

    def write_figure(self, name: str, fig) -> str:
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
        import matplotlib.pyplot as plt  # only here, where a figure already exists

        plt.close(fig)
        path = os.path.join(self.path, name)
        _atomic_write(path, buf.getvalue())
        return path

    def close(self) -> str:
        """Rename the finished folder to its final name; returns that path."""
        if not self.closed:
            os.rename(self.path, self.final_path)
            self.closed = True
            self.path = self.final_path
        return self.final_path

    def __enter__(self) -> "RunFolder":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
