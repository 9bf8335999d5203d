"""Run one experiment: ``python -m experiments.run [CONFIG] [--out DIR] [overrides]``.

CONFIG is a preset in ``configs/`` (e.g. ``pendulum_d2c``), a ``.py`` file defining
``CONFIG``, or a run's ``config.json`` (to replay it). With no CONFIG the embedded
default runs. Overrides are dotted fields, e.g. ``--task.T 20 --system.backend native``.
Bad input exits with status 2 and a one-line message naming the field, before any compile.
"""

from __future__ import annotations

import contextlib
import dataclasses
import importlib
import importlib.util
import io
import json
import os
import re
import shutil
import sys
import tempfile
import threading
import typing

from experiments.summary import summary_line, summary_screen
from mjx_surrogate.errors import ConfigError
from mjx_surrogate.runs.config import MOVED, Config, from_dict, to_dict, upgrade
from mjx_surrogate.runs.config.goal import GOALS_HELP
from mjx_surrogate.runs.extension_settings import declared, with_declared, without_declared
from mjx_surrogate.runs.validation import validate_static
from mjx_surrogate.runtime import configure_runtime

DEFAULT_PRESET = "default"
LAST_STATUS: dict = {}  # the status of this process's last run (its folder may be another's)


def preset_names() -> list[str]:
    import configs

    return configs.names()


def load_config(spec: str) -> Config:
    """A preset name, a .py file defining CONFIG, or a config.json."""
    if spec.endswith(".json"):
        if not os.path.isfile(spec):
            raise ConfigError("CONFIG", f"no such file {spec!r}")
        with open(spec) as f:
            try:
                data = json.load(f)
            except json.JSONDecodeError as exc:
                raise ConfigError("CONFIG", f"{spec!r} is not valid JSON ({exc})") from None
        return _replayed_model(from_dict(Config, upgrade(data), complete=True), spec)
    if spec.endswith(".py"):
        if not os.path.isfile(spec):
            raise ConfigError("CONFIG", f"no such file {spec!r}")
        mod_spec = importlib.util.spec_from_file_location("user_config", spec)
        module = importlib.util.module_from_spec(mod_spec)
        try:
            mod_spec.loader.exec_module(module)
        except ConfigError:
            raise
        except BaseException as exc:  # the user's file: report, never a traceback
            msg = " ".join(str(exc).split())[:200]
            raise ConfigError("CONFIG", f"{spec!r} raised {type(exc).__name__}: {msg}") from None
    else:
        if spec not in preset_names():
            raise ConfigError(
                "CONFIG",
                f"unknown preset {spec!r}; valid: {', '.join(preset_names())} (or a .py / config.json path)",
            )
        module = importlib.import_module(f"configs.{spec}")
    cfg = getattr(module, "CONFIG", None)
    if not isinstance(cfg, Config):
        raise ConfigError("CONFIG", f"{spec!r} defines no CONFIG of type mjx_surrogate.runs.config.Config")
    return cfg


def _replayed_model(cfg: Config, spec: str) -> Config:
    """A run's config.json replays the run's own compiled model (``model.mjb`` beside it,
    as ``system.model_copy``), never the MJCF file at the original path, which may have
    been edited since; the replay is named after the run (:func:`run_name`)."""
    cfg = dataclasses.replace(cfg, experiment=dataclasses.replace(cfg.experiment, name=None))
    mjb = os.path.join(os.path.dirname(os.path.abspath(spec)), "model.mjb")
    if cfg.system.name != "mjcf" or cfg.system.model_copy is not None or not os.path.isfile(mjb):
        return cfg
    return dataclasses.replace(cfg, system=dataclasses.replace(cfg.system, model_copy=mjb))


def parse_args(argv: list[str]) -> tuple[Config, str]:
    """Returns the config with overrides applied and the preset's name."""
    import tyro

    argv = list(argv)
    spec = DEFAULT_PRESET
    if argv and not argv[0].startswith("-"):
        spec = argv.pop(0)
    base = with_declared(load_config(spec))  # the extensions' settings as fields of their sections
    given = {key for key in declared() if any(a.startswith(f"--{key}.") for a in argv)}
    description = f"{__doc__ or ''}\nPresets: {', '.join(preset_names())}\n\n{GOALS_HELP}"
    if any(a in ("-h", "--help") for a in argv):
        tyro.cli(
            type(base),
            default=base,
            args=argv,
            description=description,
            prog="python -m experiments.run [CONFIG]",
        )
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(err), _unwrapped():
            cfg = tyro.cli(
                type(base),
                default=base,
                args=argv,
                description=description,
                prog="python -m experiments.run [CONFIG]",
            )
    except SystemExit:
        raise _one_line_tyro_error(err.getvalue(), argv) from None
    cfg = without_declared(cfg, Config, given)
    return cfg, run_name(spec)


def run_name(spec: str) -> str:
    """The name a run of ``spec`` gets: the preset's or file's stem; a replayed run's
    ``config.json`` gives its run's name (the folder's, less its time stamp) + ``_replay``."""
    stem = os.path.splitext(os.path.basename(spec))[0]
    if os.path.basename(spec) != "config.json":
        return stem
    folder = os.path.basename(os.path.dirname(os.path.abspath(spec)))
    folder = re.sub(r"^\d{8}-\d{6}_", "", folder)
    return f"{folder or stem}_replay"


def check_out_dir(path: str) -> None:
    """The output folder exists as a writable directory or can be created."""
    probe = os.path.abspath(path)
    while not os.path.exists(probe):
        parent = os.path.dirname(probe)
        if parent == probe:
            break
        probe = parent
    if not os.path.isdir(probe):
        raise ConfigError("experiment.out_dir", f"{probe!r} is a file, not a directory")
    if not os.access(probe, os.W_OK | os.X_OK):
        raise ConfigError("experiment.out_dir", f"{probe!r} is not writable")


_METAVARS = {"INT": "an integer", "FLOAT": "a number", "STR": "a string", "PATH": "a path"}


def _expected(metavar: str) -> str:
    """tyro's metavar in words: ``{None}|INT`` -> "an integer or None"."""
    alts = [a.strip("{}") for a in metavar.split("|")]
    words = []
    for a in alts:
        if a.startswith("[") or "..." in a:
            words.append("numbers" if "FLOAT" in a or "INT" in a else "values")
        elif a in _METAVARS:
            words.append(_METAVARS[a])
        elif a and a != "None":
            words.append("one of " + ", ".join(a.split(",")))
    words += ["None"] if "None" in alts else []
    return " or ".join(words) or metavar


def _values_after(argv: list[str], field: str) -> list[str]:
    """The tokens given after ``field`` in argv, up to the next option."""
    bare = field[2:]
    names = {"--" + bare, "--" + bare.replace("_", "-"), "--" + bare.replace("-", "_")}
    for i, a in enumerate(argv):
        if a in names or any(a.startswith(n + "=") for n in names):
            if "=" in a:
                return [a.split("=", 1)[1]]
            rest = argv[i + 1 :]
            stop = next((j for j, b in enumerate(rest) if b.startswith("--")), len(rest))
            return rest[:stop]
    return []


@contextlib.contextmanager
def _unwrapped():
    """tyro's messages rendered on one line each (a wide terminal), so that a value quoted
    in them keeps its commas and spaces as given."""
    before = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = "10000"
    try:
        yield
    finally:
        if before is None:
            os.environ.pop("COLUMNS", None)
        else:
            os.environ["COLUMNS"] = before


def _one_line_tyro_error(text: str, argv: list[str] | None = None) -> ConfigError:
    """Condense tyro's boxed message to one line naming the field and the bad value."""
    argv = argv or []
    lines = [re.sub(r"^[\s│╭╰─]+|[\s│╮╯─]+$", "", ln) for ln in text.splitlines()]
    lines = [ln for ln in lines if ln and not re.fullmatch(r"[-─\s]+", ln)]
    joined = re.sub(r"\s+", " ", " ".join(lines))
    if "Unrecognized options" in joined:
        return _unrecognized(joined, argv)
    # a field's own parser refused the value with a ConfigError (e.g. PointGoal.from_text)
    own = re.search(r"Error parsing --[\w.-]+: ([a-z_]+(?:\.[\w\[\]]+)+): (.*?) Argument helptext", joined)
    if own:
        return ConfigError(own.group(1), own.group(2))
    fields = re.findall(r"--[\w.-]*\w", joined)  # tyro writes snake_case fields with hyphens
    if not fields:
        return ConfigError("overrides", joined[:300])
    flag = fields[0]
    field = "--" + flag[2:].replace("-", "_")
    if joined.startswith("Missing") or "Missing value" in joined:
        return ConfigError(field, "needs a value")
    helptext = re.search(re.escape(flag) + r" (\S+)", joined.split("Argument helptext:", 1)[-1])
    values = _values_after(argv, flag)
    got = " ".join(repr(v) for v in values) if values else "nothing"
    choices = re.search(r"Expected one of \(([^)]*)\)", joined)
    if choices:
        return ConfigError(field, f"expects one of {choices.group(1).replace(chr(39), '')}, got {got}")
    if helptext:
        return ConfigError(field, f"expects {_expected(helptext.group(1))}, got {got}")
    reason = joined.split("Error parsing", 1)[-1].split("Got errors", 1)[0].split("Argument helptext", 1)[0]
    return ConfigError(field, reason.strip(" :.")[:300])


def _unrecognized(joined: str, argv: list[str]) -> ConfigError:
    """An unknown option (with close names), or a stray value such as ``True`` after a flag."""
    listed = joined.split("Unrecognized options:", 1)[1].split("For full helptext", 1)[0]
    listed = listed.split("Perhaps you meant", 1)[0]
    tokens = [t.strip(" ,") for t in listed.split(",") if t.strip(" ,")]
    options = [t for t in tokens if t.startswith("--")]
    if options and options[0][2:].replace("-", "_") in MOVED:
        old = options[0][2:].replace("-", "_")
        return ConfigError(options[0], f"moved to --{MOVED[old]} in version 0.5.0")
    if options:
        after = joined.split("Perhaps you meant", 1)[1] if "Perhaps you meant" in joined else ""
        similar = [f.replace("-", "_").replace("__", "--", 1) for f in re.findall(r"--[\w.-]+", after)]
        similar = [f for f in similar if f != "--help"]
        hint = f"; did you mean {', '.join(dict.fromkeys(similar[:3]))}?" if similar else ""
        return ConfigError(options[0], f"unknown field{hint} (run with --help for the valid fields)")
    stray = tokens[0] if tokens else "?"
    before = _flag_before(argv, stray)
    if before:
        parent, _, leaf = before[2:].replace("-", "_").rpartition(".")
        prefix, leaf = (f"{parent}." if parent else ""), leaf.removeprefix("no_")
        return ConfigError(
            f"--{prefix}{leaf}",
            f"a flag takes no value, got {stray!r}: write --{prefix}{leaf} to switch it on, "
            f"--{prefix}no_{leaf} to switch it off",
        )
    return ConfigError("overrides", f"unexpected value {stray!r} (options are --field value)")


def _flag_before(argv: list[str], stray: str) -> str | None:
    """The on/off flag a stray value follows in argv (``--experiment.progress False``), not
    merely its first occurrence: ``False`` may also be the value of an option that takes
    one (``--experiment.exact_oracle False``)."""
    after = [argv[i - 1] for i, a in enumerate(argv) if a == stray and i > 0 and argv[i - 1].startswith("--")]
    flags = [b for b in after if _is_flag(b)]
    return (flags or after or [None])[0]


def _is_flag(option: str) -> bool:
    """Whether ``--section.field`` (or ``--section.no_field``) names a plain bool field of
    the config, which tyro takes as a flag without a value."""
    *sections, leaf = option[2:].replace("-", "_").split(".")
    cls = Config
    for name in sections:
        cls = typing.get_type_hints(cls).get(name)
        if not dataclasses.is_dataclass(cls):
            return False
    hints = typing.get_type_hints(cls)
    return hints.get(leaf, hints.get(leaf.removeprefix("no_"))) is bool


class RunWriteFailed(Exception):
    """The run folder could not be made or written; the message is one line."""


def run(
    cfg: Config,
    name: str = "run",
    resume_from: str | None = None,
    local: bool = False,
    hard_stop: bool = False,
) -> str:
    """Run a config; returns the run folder. Raises ConfigError on bad input (before any
    compile). Every stage is written as it finishes; SIGINT/SIGTERM end the run after the
    current solver iteration with status ``interrupted``; with ``hard_stop`` (the command
    line's entry points, never a notebook's kernel) a run whose code polls for no stop is
    ended ``progress.STOP_GRACE_S`` after the signal, the running stage dropped, and the
    process exits;
    ``resume_from`` reuses the stages a previous run of the same config finished. A disk
    that refuses the run's files (full, read-only) raises :class:`RunWriteFailed` after
    the run recorded what it could, status ``failed``.

    With ``parallel.distributed`` every process runs this same call and only process 0
    writes the run folder (the others write to a temporary folder, removed at the end);
    ``local``: this process runs the experiment alone on its own devices and writes it
    (a sweep member, :mod:`experiments.reproduce`)."""
    import jax

    from mjx_surrogate import progress
    from mjx_surrogate.runs import distributed
    from mjx_surrogate.runs.experiment_kinds import runner
    from mjx_surrogate.runs.results import Interrupted, Run, WriteError

    res, parallel = _resolved(cfg, local)
    ex = res.config.experiment
    writer = local or distributed.is_writer()
    folder, out_dir = _open_folder(ex.out_dir, ex.name or name, writer)
    record = Run(folder, resume_from)
    key = jax.random.key(ex.seed)
    status, error, write_failure = "failed", None, None
    guard = (
        progress.stop_on_signals(on_stuck=(lambda: _stop_now(record)) if hard_stop else None)
        if threading.current_thread() is threading.main_thread()
        else contextlib.nullcontext()
    )
    progress.clear_stop()
    try:
        with guard:
            _write_inputs(folder, res, parallel)
            if not local:  # the processes enter the experiment's first collective together
                distributed.barrier(f"run {ex.name or name}: inputs resolved")
            status = runner(ex.kind)(res, record, key)
            optimum = next((k for k in ("X_star", "d2c_X") if k in record.arrays), None)  # d2c's: d2c_X
            if ex.video and writer and res.system.mj_model is not None and optimum is not None:
                record.video("optimum.mp4", [optimum], float(res.system.dt))
    except (Interrupted, KeyboardInterrupt) as exc:
        status, error = "interrupted", exc
    except Exception as exc:  # keep what was produced, say what happened
        status, error = "failed", exc
    finally:
        try:
            path = record.finish(status, error)
        except WriteError as exc:
            write_failure, path = exc, folder.path
        progress.clear_stop()
    LAST_STATUS["status"] = record.metrics.get("status")
    if not writer:
        shutil.rmtree(out_dir, ignore_errors=True)
        return path
    _raise_write_failure(write_failure or (error if isinstance(error, WriteError) else None), path)
    _write_page(path)
    print(summary_screen(record.metrics, path))
    return path


def _resolved(cfg: Config, local: bool):
    """Validate (before joining other processes, which may wait for minutes), configure the
    runtime and the processes, resolve; the config records the precision actually used (a
    session may already run in x64)."""
    import jax

    from mjx_surrogate.runs import distributed
    from mjx_surrogate.runs.model_defaults import default_x64
    from mjx_surrogate.runs.resolution import resolve

    validate_static(cfg)
    check_out_dir(cfg.experiment.out_dir)
    configure_runtime(x64=(cfg.experiment.x64 or default_x64(cfg.system.name)) or None)
    parallel = distributed.initialize(cfg.parallel)
    x64 = bool(jax.config.jax_enable_x64)
    cfg = dataclasses.replace(cfg, experiment=dataclasses.replace(cfg.experiment, x64=x64))
    return resolve(cfg, local=local), parallel


def _open_folder(out_dir: str, name: str, writer: bool):
    """The run folder (in a temporary folder for a process that does not write) and where."""
    from mjx_surrogate.runs import distributed
    from mjx_surrogate.runs.results import RunFolder, WriteError

    if not writer:
        out_dir = tempfile.mkdtemp(prefix=f"mjx_surrogate_p{distributed.process_index()}_")
    try:
        folder = RunFolder(out_dir, name)
    except WriteError as exc:
        raise RunWriteFailed(f"no run folder could be made in {out_dir}: {exc}") from None
    for path in folder.recovered:
        print(f"note: recovered a run folder left unfinished by a killed process: {path}", file=sys.stderr)
    return folder, out_dir


def _raise_write_failure(failure, path: str) -> None:
    """A disk that refused the run's files: :class:`RunWriteFailed`, saying what was kept."""
    if failure is None:
        return
    cause = failure.cause
    raise RunWriteFailed(
        f"run folder {path}: cannot write {os.path.basename(failure.path)} "
        f"([Errno {cause.errno}] {cause.strerror or cause}); status failed, "
        "the stages finished before are kept"
    )


def _write_page(path: str) -> None:
    """The run folder's report.html (experiments/page.py); a failure is said, never raised."""
    from experiments import page

    try:
        page.write(path)
    except Exception as exc:  # the record is complete without it
        print(f"note: {page.PAGE} not written: {type(exc).__name__}: {exc}", file=sys.stderr)


def _write_inputs(folder, res, parallel: dict) -> None:
    """The resolved config, the exact model and the versions, into the run folder."""
    from mjx_surrogate.runs.results import versions

    folder.write_json("config.json", to_dict(res.config))
    if res.system.mj_model is not None:
        if res.system.xml:  # a replay's model, loaded from a run's model.mjb, has no MJCF text
            folder.write_text("model.xml", res.system.xml)
        folder.write_bytes("model.mjb", model_bytes(res.system.mj_model))
    elif res.system.source is not None:  # a user's function: its file, as the run used it
        with open(res.system.source, "rb") as f:
            folder.write_bytes("system_source.py", f.read())
    folder.write_json("versions.json", versions() | {"parallel": parallel | _devices(res.system)})


def _stop_now(record) -> None:
    """The stop watchdog's action (another thread): a stop request found code that does not
    poll for one (a compile, a long jitted call); end the run at once, keeping every stage
    written before, and leave the process with the interrupted status."""
    from mjx_surrogate.progress import STOP_GRACE_S
    from mjx_surrogate.runs.results import EXIT_CODES

    if record.current:
        reason = (
            f"stopped by a signal; stage {record.current!r} did not end within {STOP_GRACE_S:g} s "
            "and its partial work was not kept; the stages finished before are kept"
        )
    else:
        reason = (
            f"stopped by a signal; the run did not end within {STOP_GRACE_S:g} s after its last "
            "stage; every stage it finished is kept"
        )
    if not record.abort(reason):
        return  # the run is ending by itself
    try:
        _write_page(record.folder.path)
        print(summary_line(record.metrics, record.folder.path), flush=True)
        sys.stderr.flush()
    except Exception:  # e.g. the reader of stdout is gone: the record is written, exit anyway
        pass
    finally:
        os._exit(EXIT_CODES["interrupted"])


def _devices(system) -> dict:
    """The devices a run's batched work was spread over."""
    import jax

    devices = jax.local_devices()[:1] if system.mesh is None else list(system.mesh.devices.flat)
    return {"mesh_devices": len(devices), "platform": devices[0].platform}


def model_bytes(m) -> bytes:
    """The compiled model as MJB: self-contained (meshes and textures included)."""
    import mujoco
    import numpy as np

    buf = np.zeros(mujoco.mj_sizeModel(m), np.uint8)
    mujoco.mj_saveModel(m, None, buf)
    return buf.tobytes()


def main(argv: list[str] | None = None) -> int:
    """CLI entry; exit status 0 (converged, stalled, max_iter, completed), 1 (diverged,
    failed), 2 (bad input, nothing run), 130 (interrupted)."""
    from mjx_surrogate.runs.results import EXIT_CODES

    argv = sys.argv[1:] if argv is None else argv
    try:
        cfg, name = parse_args(argv)
        run(cfg, name, hard_stop=True)
    except ConfigError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except RunWriteFailed as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    return EXIT_CODES.get(LAST_STATUS.get("status"), 1)


if __name__ == "__main__":
    sys.exit(main())
