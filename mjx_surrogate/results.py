"""Run folders and the run record: every finished stage on disk as soon as it finishes.

A run is assembled in ``<out_dir>/.<name>.partial`` and renamed to ``<out_dir>/<name>``
when it ends, whatever the outcome (``metrics.json`` says which), so an existing folder is
never overwritten. Inside, every file is written atomically, and :class:`Run` rewrites
``metrics.json`` and ``arrays.npz`` whole after every stage; a failed figure is reported
next to what succeeded and never discards a stage. A folder left ``.partial`` by a killed
process (SIGKILL, power loss) is recovered by the next run into the same ``out_dir``:
renamed to its final name with status ``killed``, its finished stages intact and
resumable (``Run(resume_from=...)``). Schema: docs/results.md.
"""

from __future__ import annotations

import datetime
import glob
import io
import json
import math
import os
import platform
import socket
import sys
import tempfile
import time
import traceback
from importlib import metadata
from typing import Any, Callable

import numpy as np

from mjx_surrogate import progress

# Run statuses (docs/results.md); the CLI's exit status follows them.
SUCCESS = ("converged", "stalled", "max_iter", "completed")
EXIT_CODES = {**{s: 0 for s in SUCCESS}, "diverged": 1, "failed": 1, "killed": 1, "interrupted": 130}


class Interrupted(Exception):
    """A stop was requested (SIGINT/SIGTERM); the run ends with status ``interrupted``."""


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
    fd, tmp = tempfile.mkstemp(dir=os.path.dirname(path), prefix=".tmp-")
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


def jsonable(obj: Any) -> Any:
    """Nested containers and arrays -> JSON values; non-finite floats become strings
    ("nan", "inf", "-inf") so that a written file always loads back exactly."""
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if hasattr(obj, "tolist"):
        return jsonable(obj.tolist())
    if isinstance(obj, float) and not math.isfinite(obj):
        return "nan" if math.isnan(obj) else ("inf" if obj > 0 else "-inf")
    return obj


_NONFINITE = {"nan": math.nan, "inf": math.inf, "-inf": -math.inf}


def restore_nonfinite(obj: Any) -> Any:
    """Inverse of :func:`jsonable` for numbers: "nan"/"inf"/"-inf" strings become floats."""
    if isinstance(obj, dict):
        return {k: restore_nonfinite(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [restore_nonfinite(v) for v in obj]
    if isinstance(obj, str) and obj in _NONFINITE:
        return _NONFINITE[obj]
    return obj


def read_json(path: str) -> Any:
    """A JSON file written by :class:`RunFolder`, non-finite numbers restored."""
    with open(path) as f:
        return restore_nonfinite(json.load(f))


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def recover_stale(out_dir: str) -> list[str]:
    """Rename folders left ``.partial`` by dead processes of this host to their final names
    with status ``killed``; returns the recovered paths."""
    recovered = []
    for partial in sorted(glob.glob(os.path.join(out_dir, ".*.partial"))):
        try:
            with open(os.path.join(partial, ".owner")) as f:
                owner = json.load(f)
        except (OSError, ValueError):
            owner = {}
        if owner.get("host") == socket.gethostname() and _alive(int(owner.get("pid", -1))):
            continue  # a live run
        if owner and owner.get("host") != socket.gethostname():
            continue  # another host's run on a shared file system: not ours to judge
        final = os.path.join(out_dir, os.path.basename(partial)[1 : -len(".partial")])
        if os.path.exists(final):
            continue
        mpath = os.path.join(partial, "metrics.json")
        try:
            with open(mpath) as f:
                metrics = json.load(f)
        except (OSError, ValueError):
            metrics = {}
        metrics["status"] = "killed"
        metrics["error"] = "the process ended without closing the run (SIGKILL or a crash)"
        _atomic_write(mpath, (json.dumps(jsonable(metrics), indent=2) + "\n").encode())
        os.rename(partial, final)
        recovered.append(final)
    return recovered


class RunFolder:
    """A run's output folder; files appear under the final name when it is closed."""

    def __init__(self, out_dir: str, name: str):
        self.recovered = recover_stale(out_dir) if os.path.isdir(out_dir) else []
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
        self.write_json(".owner", {"pid": os.getpid(), "host": socket.gethostname()})

    def write_text(self, name: str, text: str) -> str:
        path = os.path.join(self.path, name)
        _atomic_write(path, text.encode())
        return path

    def write_json(self, name: str, obj: Any) -> str:
        return self.write_text(name, json.dumps(jsonable(obj), indent=2, allow_nan=False) + "\n")

    def write_bytes(self, name: str, data: bytes) -> str:
        path = os.path.join(self.path, name)
        _atomic_write(path, data)
        return path

    def write_arrays(self, name: str, arrays: dict[str, Any]) -> str:
        buf = io.BytesIO()
        np.savez_compressed(buf, **{k: np.asarray(v) for k, v in arrays.items()})
        return self.write_bytes(name, buf.getvalue())

    def write_figure(self, name: str, fig) -> str:
        buf = io.BytesIO()
        try:
            fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
        finally:
            import matplotlib.pyplot as plt  # only here, where a figure already exists

            plt.close(fig)
        return self.write_bytes(name, buf.getvalue())

    def close(self) -> str:
        """Rename the folder to its final name; returns that path."""
        if not self.closed:
            owner = os.path.join(self.path, ".owner")
            if os.path.exists(owner):
                os.unlink(owner)
            os.rename(self.path, self.final_path)
            self.closed = True
            self.path = self.final_path
        return self.final_path


def load_run(path: str) -> tuple[dict, dict]:
    """(metrics, arrays) of a run folder (arrays as NumPy)."""
    metrics = read_json(os.path.join(path, "metrics.json"))
    arrays = {}
    npz = os.path.join(path, "arrays.npz")
    if os.path.exists(npz):
        with np.load(npz) as z:
            arrays = {k: z[k] for k in z.files}
    return metrics, arrays


def _get_path(d: dict, name: str):
    for part in name.split("/"):
        d = d.get(part, {}) if isinstance(d, dict) else {}
    return d


def _set_path(d: dict, name: str, value) -> None:
    *parents, last = name.split("/")
    for part in parents:
        d = d.setdefault(part, {})
    d[last] = value


class Run:
    """The record of one run: stages, figures and the status, on disk after each change.

    ``stage(name, compute)`` runs ``compute() -> (metrics, arrays)``, stores the metrics
    under ``metrics[name]`` (a name "a/b" under ``metrics["a"]["b"]``) and the arrays in
    ``arrays.npz``, and returns them; with
    ``resume_from`` a stage finished there is loaded instead of computed (same config and
    seed, so the same result). A stop request ends the run after the current stage.
    """

    def __init__(self, folder: RunFolder, resume_from: str | None = None):
        self.folder = folder
        self.metrics: dict = {"status": "running", "stages": {}, "figures": {}}
        self.arrays: dict = {}
        self.t0 = time.perf_counter()
        self._previous = load_run(resume_from) if resume_from else None
        if resume_from:
            self.metrics["resumed_from"] = os.path.abspath(resume_from)

    def _flush(self) -> None:
        self.metrics["wall_time_s"] = time.perf_counter() - self.t0
        self.folder.write_arrays("arrays.npz", self.arrays)
        self.folder.write_json("metrics.json", self.metrics)

    def set(self, key: str, value: Any) -> None:
        self.metrics[key] = value
        self._flush()

    def add_arrays(self, arrays: dict) -> None:
        self.arrays.update({k: np.asarray(v) for k, v in arrays.items()})
        self._flush()

    def _resumable(self, name: str):
        if self._previous is None:
            return None
        metrics, arrays = self._previous
        info = metrics.get("stages", {}).get(name, {})
        if info.get("status") != "done" or not all(k in arrays for k in info.get("arrays", [])):
            return None
        return _get_path(metrics, name), {k: arrays[k] for k in info.get("arrays", [])}

    def stage(self, name: str, compute: Callable[[], tuple[dict, dict]]) -> tuple[dict, dict]:
        """Run (or resume) one stage and write it; re-raises a failure after recording it."""
        if progress.stop_requested():
            raise Interrupted(f"before stage {name!r}")
        t0 = time.perf_counter()
        cached = self._resumable(name)
        try:
            metrics, arrays = cached if cached is not None else compute()
        except Exception as exc:
            self.metrics["stages"][name] = {
                "status": "failed",
                "error": f"{type(exc).__name__}: {exc}",
                "wall_s": time.perf_counter() - t0,
            }
            self._flush()
            raise
        arrays = {k: np.asarray(v) for k, v in arrays.items()}
        interrupted = progress.stop_requested()
        _set_path(self.metrics, name, metrics)
        self.metrics["stages"][name] = {
            "status": "interrupted" if interrupted else "done",
            "wall_s": time.perf_counter() - t0,
            "arrays": sorted(arrays),
            **({"resumed": True} if cached is not None else {}),
        }
        self.arrays.update(arrays)
        self._flush()
        if interrupted:
            raise Interrupted(f"during stage {name!r}")
        return metrics, arrays

    def figure(self, name: str, draw: Callable[[], Any]) -> bool:
        """Draw and write one figure; a failure is recorded, never raised."""
        try:
            self.folder.write_figure(name, draw())
            self.metrics["figures"][name] = "written"
            ok = True
        except Exception as exc:
            self.metrics["figures"][name] = {"status": "failed", "error": f"{type(exc).__name__}: {exc}"}
            ok = False
        self._flush()
        return ok

    def finish(self, status: str, error: BaseException | None = None) -> str:
        """Write the final status (and the error, if any), close the folder."""
        self.metrics["status"] = status
        if error is not None:
            self.metrics["error"] = f"{type(error).__name__}: {error}"
            if status == "failed":
                self.metrics["traceback"] = "".join(traceback.format_exception(error))
        self._flush()
        return self.folder.close()
