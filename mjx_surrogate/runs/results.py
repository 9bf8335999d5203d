"""Run folders and the run record: every finished stage on disk as soon as it finishes.

A run is assembled in ``<out_dir>/.<name>.partial`` and renamed to ``<out_dir>/<name>``
when it ends, whatever the outcome (``metrics.json`` says which), so an existing folder is
never overwritten. Inside, every file is written atomically with the permissions the umask
gives, and :class:`Run` rewrites ``metrics.json`` and ``arrays.npz`` whole after every
stage; a failed figure is reported next to what succeeded and never discards a stage.

Processes writing into one ``out_dir`` (an array job) take turns on an exclusive lock on
the directory to pick a name, create the folder with its ``.owner``
record, recover stale folders and rename a finished one, so none of them sees another's
half-made folder. A folder left ``.partial`` by a killed process (SIGKILL, power loss) is
recovered by the next run into the same ``out_dir``: renamed to its final name with status
``killed``, its finished stages intact and resumable (``Run(resume_from=...)``); one whose
run had already recorded its end (it could only not be renamed) keeps that status. A write
that fails (a full disk, a folder made read-only) raises :class:`WriteError`, naming the
file and the cause. Schema: docs/results.md.
"""

from __future__ import annotations

import contextlib
import datetime
import errno
import glob
import io
import itertools
import json
import math
import os
import platform
import socket
import subprocess
import sys
import tempfile
import threading
import time
import traceback
from importlib import metadata
from typing import Any, Callable

import numpy as np

from mjx_surrogate import progress
from mjx_surrogate.errors import describe

try:
    import fcntl
except ImportError:  # not POSIX: no lock, names are still unique within one process
    fcntl = None

# Run statuses (docs/results.md); the CLI's exit status follows them.
SUCCESS = ("converged", "stationary", "stalled", "max_iter", "completed")
EXIT_CODES = {**{s: 0 for s in SUCCESS}, "diverged": 1, "failed": 1, "killed": 1, "interrupted": 130}


class Interrupted(Exception):
    """A stop was requested (SIGINT/SIGTERM); the run ends with status ``interrupted``."""


class WriteError(OSError):
    """A file of a run folder could not be written (or the folder not renamed)."""

    def __init__(self, path: str, cause: OSError):
        super().__init__(cause.errno, cause.strerror or str(cause))
        self.path = path
        self.cause = cause

    def __str__(self) -> str:
        what = f"[Errno {self.cause.errno}] {self.cause.strerror}" if self.cause.strerror else str(self.cause)
        return f"cannot write {self.path}: {what}"


def versions() -> dict[str, str]:
    """Versions of python and the numerical stack, for the run folder."""
    out = {"python": sys.version.split()[0], "platform": platform.platform()}
    for pkg in (
        "jax",
        "jaxlib",
        "mujoco",
        "mujoco-mjx",
        "flax",
        "optax",
        "numpy",
        "imageio",
        "imageio-ffmpeg",
        "mjx_surrogate",
    ):
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            out[pkg] = "not installed"
    out["XLA_FLAGS"] = os.environ.get("XLA_FLAGS", "")
    out["mjx_surrogate_commit"] = code_revision()
    return out


def code_revision(root: str | None = None) -> str:
    """The git commit of the checkout this package runs from (or of ``root``), ``+dirty``
    where its tracked files other than the docs (``docs/``, Markdown) differ from it, or
    ``unknown`` outside a git checkout (an installed wheel). The docs do not count: a report
    that rewrites its own figures under ``docs/`` describes the code as committed."""
    root = root or os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

    def git(*args: str) -> str | None:
        try:
            done = subprocess.run(
                ["git", "-C", root, *args], capture_output=True, text=True, timeout=10, check=True
            )
        except (OSError, subprocess.SubprocessError):
            return None
        return done.stdout.strip()

    head = git("rev-parse", "--short=12", "HEAD")
    if not head or git("rev-parse", "--show-toplevel") != os.path.realpath(root):
        return "unknown"
    changed = git("status", "--porcelain", "--untracked-files=no", "--", ".", ":!docs", ":!*.md")
    return head + ("+dirty" if changed else "")


def _umask() -> int:
    """The process's umask, read without changing it where the OS allows."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)  # elsewhere: set and restore at once
    os.umask(mask)
    return mask


def _atomic_write(path: str, data: bytes) -> None:
    """Write ``path`` whole or not at all, mode 0666 less the umask (as ``open`` would);
    raises :class:`WriteError`."""
    try:
        fd, tmp = tempfile.mkstemp(dir=os.path.dirname(path), prefix=".tmp-")
    except OSError as exc:
        raise WriteError(path, exc) from exc
    try:
        os.fchmod(fd, 0o666 & ~_umask())
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(exc, OSError) and not isinstance(exc, WriteError):
            raise WriteError(path, exc) from exc
        raise


def _overwrite_in_place(path: str, data: bytes) -> None:
    """Last resort on a full disk: rewrite an existing file in its own blocks (truncate,
    write); not atomic. Raises :class:`WriteError`."""
    try:
        with open(path, "r+b" if os.path.exists(path) else "wb") as f:
            f.truncate(0)
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
    except OSError as exc:
        raise WriteError(path, exc) from exc


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


@contextlib.contextmanager
def out_dir_lock(out_dir: str):
    """Hold the exclusive lock of ``out_dir`` (see the module's docstring): ``flock`` on the
    directory itself, so no lock file is left behind and a full or read-only disk still
    locks. Where the directory cannot be opened the block runs unlocked."""
    fd = None
    if fcntl is not None:
        try:
            fd = os.open(out_dir, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
        except OSError:
            fd = None
    try:
        if fd is not None:
            fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        if fd is not None:
            os.close(fd)  # releases the lock


def _owner(partial: str) -> dict:
    try:
        with open(os.path.join(partial, ".owner")) as f:
            return json.load(f)
    except (OSError, ValueError):
        return {}


def recover_stale(out_dir: str) -> list[str]:
    """Rename folders left ``.partial`` by dead processes of this host to their final names
    with status ``killed`` (or the end status they had recorded); returns their paths."""
    with out_dir_lock(out_dir):
        return _recover_stale_locked(out_dir)


def _recover_stale_locked(out_dir: str) -> list[str]:
    recovered = []
    for partial in sorted(glob.glob(os.path.join(out_dir, ".*.partial"))):
        owner = _owner(partial)
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
        if metrics.get("status", "running") == "running":
            metrics["status"] = "killed"
            metrics["error"] = "the process ended without closing the run (SIGKILL or a crash)"
        else:  # the run recorded its end but could not rename its folder
            metrics["recovered"] = "the run ended but could not rename its folder; a later run did"
        try:
            _atomic_write(mpath, (json.dumps(jsonable(metrics), indent=2) + "\n").encode())
            os.rename(partial, final)
        except OSError:
            continue  # still unwritable: left for a later run
        with contextlib.suppress(OSError):
            os.unlink(os.path.join(final, ".owner"))
        recovered.append(final)
    return recovered


class RunFolder:
    """A run's output folder; files appear under the final name when it is closed.
    Raises :class:`WriteError` where the folder cannot be made."""

    def __init__(self, out_dir: str, name: str):
        try:
            os.makedirs(out_dir, exist_ok=True)
        except OSError as exc:
            raise WriteError(out_dir, exc) from exc
        with out_dir_lock(out_dir):
            self.recovered = _recover_stale_locked(out_dir)
            self.final_path, self.path = self._reserve(out_dir, name)
            try:
                self.write_json(".owner", {"pid": os.getpid(), "host": socket.gethostname()})
            except WriteError:
                with contextlib.suppress(OSError):
                    os.rmdir(self.path)
                raise
        self.closed = False

    @staticmethod
    def _reserve(out_dir: str, name: str) -> tuple[str, str]:
        """(final, partial) paths of a name free in both forms; the partial folder made."""
        base = f"{datetime.datetime.now().strftime('%Y%m%d-%H%M%S')}_{name}"
        for k in itertools.count():
            final = os.path.join(out_dir, base if k == 0 else f"{base}_{k}")
            partial = os.path.join(out_dir, "." + os.path.basename(final) + ".partial")
            if os.path.exists(final) or os.path.exists(partial):
                continue
            try:
                os.mkdir(partial)
            except FileExistsError:
                continue
            except OSError as exc:
                raise WriteError(partial, exc) from exc
            return final, partial

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
        """Rename the folder to its final name; returns that path. Raises
        :class:`WriteError` (the folder stays ``.partial``, its owner recorded)."""
        if not self.closed:
            out_dir = os.path.dirname(self.final_path)
            with out_dir_lock(out_dir):
                if os.path.exists(self.final_path):  # only another program could have made it
                    raise WriteError(self.final_path, OSError(errno.EEXIST, "exists already"))
                try:
                    os.rename(self.path, self.final_path)
                except OSError as exc:
                    raise WriteError(self.final_path, exc) from exc
            self.closed = True
            self.path = self.final_path
            with contextlib.suppress(OSError):
                os.unlink(os.path.join(self.path, ".owner"))
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
    ``arrays.npz``, and returns them; with ``resume_from`` a stage finished there is loaded
    instead of computed (same config and seed, so the same result). A stage whose compute
    returns is ``done``, unless its metrics say its solve was cut short (``"status":
    "interrupted"``), which ends the run; after a stop request the next stage does not
    start. Thread-safe: :meth:`abort` may end the run from another thread.
    """

    def __init__(self, folder: RunFolder, resume_from: str | None = None):
        self.folder = folder
        self.metrics: dict = {"status": "running", "stages": {}, "figures": {}}
        self.arrays: dict = {}
        self.t0 = time.perf_counter()
        self.current: str | None = None  # the stage being computed
        self._lock = threading.RLock()
        self._ending = False  # finish() or abort() has begun
        self._on_disk: set[str] = set()  # the arrays the last arrays.npz written holds
        self._previous = load_run(resume_from) if resume_from else None
        if resume_from:
            self.metrics["resumed_from"] = os.path.abspath(resume_from)

    def _flush(self, arrays: bool = True) -> None:
        with self._lock:
            self.metrics["wall_time_s"] = time.perf_counter() - self.t0
            if arrays:
                self.folder.write_arrays("arrays.npz", self.arrays)
                self._on_disk = set(self.arrays)
            self.folder.write_json("metrics.json", self.metrics)

    def set(self, key: str, value: Any) -> None:
        with self._lock:
            self.metrics[key] = value
            self._flush()

    def add_arrays(self, arrays: dict) -> None:
        with self._lock:
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
        self.current = name
        try:
            metrics, arrays = cached if cached is not None else compute()
        except progress.Stopped:  # a stop seen between the stage's own steps
            with self._lock:
                self.current = None
                self.metrics["stages"][name] = {
                    "status": "interrupted",
                    "wall_s": time.perf_counter() - t0,
                    "arrays": [],
                }
                self._flush(arrays=False)
            raise Interrupted(f"during stage {name!r}") from None
        except Exception as exc:
            with self._lock:
                self.current = None
                self.metrics["stages"][name] = {
                    "status": "failed",
                    "error": f"{type(exc).__name__}: {exc}",
                    "wall_s": time.perf_counter() - t0,
                }
                self._flush()
            raise
        arrays = {k: np.asarray(v) for k, v in arrays.items()}
        cut_short = isinstance(metrics, dict) and metrics.get("status") == "interrupted"
        with self._lock:
            if self._ending:  # aborted meanwhile: the record is closed
                raise Interrupted(f"during stage {name!r}")
            self.current = None
            _set_path(self.metrics, name, metrics)
            self.metrics["stages"][name] = {
                "status": "interrupted" if cut_short else "done",
                "wall_s": time.perf_counter() - t0,
                "arrays": sorted(arrays),
                **({"resumed": True} if cached is not None else {}),
            }
            self.arrays.update(arrays)
            self._flush()
        if cut_short:
            raise Interrupted(f"during stage {name!r}")
        return metrics, arrays

    def figure(self, name: str, draw: Callable[[], Any]) -> bool:
        """Draw and write one figure; a failure to draw is recorded, never raised. After a
        stop request it is recorded as skipped, not drawn: drawing polls for no stop."""
        if progress.stop_requested():
            skipped = {"status": "skipped", "error": "the run was stopped before it was drawn"}
            with self._lock:
                self.metrics["figures"][name] = skipped
                self._flush(arrays=False)
            return False
        try:
            self.folder.write_figure(name, draw())
            entry, ok = "written", True
        except WriteError:
            raise
        except Exception as exc:
            entry, ok = {"status": "failed", "error": f"{type(exc).__name__}: {exc}"}, False
        with self._lock:
            self.metrics["figures"][name] = entry
            self._flush(arrays=False)
        return ok

    def video(self, name: str, keys: list[str], dt: float, labels: list[str] | None = None) -> bool:
        """Render the trajectories ``keys`` of the run's arrays on its ``model.mjb`` into the
        MP4 ``name`` (:mod:`mjx_surrogate.runs.video`, side by side, each named by ``labels``
        if given); a failure is recorded and
        said in one line on stderr, never raised."""
        from mjx_surrogate.runs.video import still_path, write_video

        self._flush()
        folder = self.folder.path
        reason = write_video(
            os.path.join(folder, "model.mjb"),
            os.path.join(folder, "arrays.npz"),
            keys,
            os.path.join(folder, name),
            dt,
            labels=labels,
        )
        entry = (
            {"status": "written", "trajectories": keys, "still": os.path.basename(still_path(name))}
            if reason is None
            else {"status": "skipped", "reason": reason}
        )
        if reason is not None:
            print(f"note: video {name} not written: {reason}", file=sys.stderr)
        with self._lock:
            self.metrics.setdefault("videos", {})[name] = entry
            self._flush(arrays=False)
        return reason is None

    def finish(self, status: str, error: BaseException | None = None) -> str:
        """Write the final status (and the error, if any), close the folder; returns its
        path. Where the disk refuses, as much of the record as fits is written (the
        metrics before the arrays, in place as a last resort), the folder still gets its
        final name, and :class:`WriteError` is raised after."""
        with self._lock:
            if self._ending and self.folder.closed:  # aborted (another thread): keep that record
                return self.folder.final_path
            self._ending = True
            self.metrics["status"] = status
            if error is not None:
                self.metrics["error"] = describe(error)
                if status == "failed" and not isinstance(error, WriteError):
                    self.metrics["traceback"] = "".join(traceback.format_exception(error))
            failure = self._write_end()
            try:
                path = self.folder.close()
            except WriteError as exc:  # e.g. out_dir made read-only: say so inside the folder
                self.metrics["status"] = "failed"
                self.metrics["error"] = f"WriteError: {exc}"
                self._write_end()
                with contextlib.suppress(OSError):  # ended: a later run may give it its name
                    os.unlink(os.path.join(self.folder.path, ".owner"))
                raise
            if failure is not None:
                raise failure
            return path

    def _write_end(self) -> WriteError | None:
        """Write the record as far as the disk allows; the first failure, or None."""
        try:
            self._flush()
            return None
        except WriteError as exc:
            first = exc
        for stage in self.metrics["stages"].values():  # finished, but its arrays are not on disk
            lost = [k for k in stage.get("arrays", []) if k not in self._on_disk]
            if lost:
                stage["arrays_not_written"] = lost
        if self.metrics.get("status") != "failed":  # the run did not fail, its record did
            self.metrics["status"], self.metrics["error"] = "failed", f"WriteError: {first}"
        text = (json.dumps(jsonable(self.metrics), indent=2) + "\n").encode()
        minimal = {k: self.metrics.get(k) for k in ("status", "error", "stages")}
        path = os.path.join(self.folder.path, "metrics.json")
        for attempt in (
            lambda: self.folder.write_json("metrics.json", self.metrics),
            lambda: _overwrite_in_place(path, text),
            lambda: _overwrite_in_place(path, json.dumps(jsonable(minimal)).encode()),
        ):
            try:
                attempt()
                break
            except WriteError:
                continue
        return first

    def abort(self, reason: str) -> bool:
        """End the run now with status ``interrupted`` (from any thread): the stage being
        computed is marked ``interrupted`` and its partial work dropped; everything written
        before is kept. Only ``metrics.json`` is written, so this takes milliseconds.
        Returns False, doing nothing, when the run is already ending."""
        with self._lock:
            if self._ending:
                return False
            self._ending = True
            if self.current is not None:
                self.metrics["stages"][self.current] = {"status": "interrupted", "arrays": []}
            self.metrics["status"], self.metrics["error"] = "interrupted", reason
            try:
                self._flush(arrays=False)
            except WriteError:
                pass
            with contextlib.suppress(WriteError):
                self.folder.close()
            return True
