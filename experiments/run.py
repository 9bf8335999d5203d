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

from mjx_surrogate.config import Config, from_dict, to_dict, validate_static
from mjx_surrogate.errors import ConfigError
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
        return from_dict(Config, data, complete=True)
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
        raise ConfigError("CONFIG", f"{spec!r} defines no CONFIG of type mjx_surrogate.config.Config")
    return cfg


def parse_args(argv: list[str]) -> tuple[Config, str]:
    """Returns the config with overrides applied and the preset's name."""
    import tyro

    argv, out = _take_out(list(argv))
    spec = DEFAULT_PRESET
    if argv and not argv[0].startswith("-"):
        spec = argv.pop(0)
    base = load_config(spec)
    description = (__doc__ or "") + "\nPresets: " + ", ".join(preset_names())
    if any(a in ("-h", "--help") for a in argv):
        tyro.cli(
            Config,
            default=base,
            args=argv,
            description=description,
            prog="python -m experiments.run [CONFIG]",
        )
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(err):
            cfg = tyro.cli(
                Config,
                default=base,
                args=argv,
                description=description,
                prog="python -m experiments.run [CONFIG]",
            )
    except SystemExit:
        raise _one_line_tyro_error(err.getvalue()) from None
    if out is not None:
        cfg = dataclasses.replace(cfg, experiment=dataclasses.replace(cfg.experiment, out_dir=out))
    name = os.path.splitext(os.path.basename(spec))[0]
    return cfg, name


def _take_out(argv: list[str]) -> tuple[list[str], str | None]:
    """Remove ``--out DIR`` / ``--out=DIR`` (given at most once) from argv."""
    rest, outs, i = [], [], 0
    while i < len(argv):
        a = argv[i]
        if a == "--out":
            if i + 1 >= len(argv) or argv[i + 1].startswith("--"):
                raise ConfigError("--out", "needs a directory")
            outs.append(argv[i + 1])
            i += 2
            continue
        if a.startswith("--out="):
            outs.append(a.split("=", 1)[1])
        else:
            rest.append(a)
        i += 1
    if len(outs) > 1:
        raise ConfigError("--out", f"given {len(outs)} times ({', '.join(outs)}); give one directory")
    if outs and not outs[0]:
        raise ConfigError("--out", "needs a directory")
    return rest, (outs[0] if outs else None)


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


def _one_line_tyro_error(text: str) -> ConfigError:
    """Condense tyro's boxed message to one line naming the field."""
    lines = [re.sub(r"^[\s│╭╰─]+|[\s│╮╯─]+$", "", ln) for ln in text.splitlines()]
    lines = [ln for ln in lines if ln and "helptext" not in ln.lower() and not re.fullmatch(r"[-─\s]+", ln)]
    lines = [re.sub(r"\s*-{3,}\s*", "", ln) for ln in lines]
    body = " ".join(lines[1:4] if len(lines) > 1 else lines)
    fields = re.findall(r"--[\w.-]*\w", body)  # tyro writes snake_case fields with hyphens
    field = "--" + fields[0][2:].replace("-", "_") if fields else "overrides"
    if "Unrecognized" in body:
        joined = " ".join(lines)
        after = joined.split("Perhaps you meant", 1)[1] if "Perhaps you meant" in joined else ""
        similar = [f.replace("-", "_").replace("__", "--", 1) for f in re.findall(r"--[\w.-]+", after)]
        hint = f"; did you mean {', '.join(dict.fromkeys(similar[:3]))}?" if similar else ""
        return ConfigError(field, f"unknown field{hint} (run with --help for the valid fields)")
    return ConfigError(field, re.sub(r"\s+", " ", body)[:300])


def kinds():
    from experiments import (
        analysis_study,
        control_study,
        d2c_study,
        horizon_study,
        predict_study,
        rollout_study,
        theory_study,
    )

    return {
        "rollout": rollout_study.run,
        "d2c": d2c_study.run,
        "predict": predict_study.run,
        "analysis": analysis_study.run,
        "theory": theory_study.run,
        "control": control_study.run,
        "horizon": horizon_study.run,
    }


def run(cfg: Config, name: str = "run", resume_from: str | None = None, local: bool = False) -> str:
    """Run a config; returns the run folder. Raises ConfigError on bad input (before any
    compile). Every stage is written as it finishes; SIGINT/SIGTERM end the run after the
    current solver iteration with status ``interrupted``; ``resume_from`` reuses the stages
    a previous run of the same config finished.

    With ``parallel.distributed`` every process runs this same call and only process 0
    writes the run folder (the others write to a temporary folder, removed at the end);
    ``local``: this process runs the experiment alone on its own devices and writes it
    (a sweep member, :mod:`experiments.reproduce`)."""
    import jax

    from mjx_surrogate import distributed, progress
    from mjx_surrogate.resolution import resolve
    from mjx_surrogate.results import Interrupted, Run, RunFolder, versions

    validate_static(cfg)  # before joining other processes, which may wait for minutes
    configure_runtime(x64=cfg.experiment.x64 or None)
    parallel = distributed.initialize(cfg.parallel)
    # Record the precision actually used (a session may already run in x64).
    cfg = dataclasses.replace(
        cfg, experiment=dataclasses.replace(cfg.experiment, x64=bool(jax.config.jax_enable_x64))
    )
    res = resolve(cfg, local=local)
    ex = res.config.experiment
    check_out_dir(ex.out_dir)
    writer = local or distributed.is_writer()
    out_dir = (
        ex.out_dir if writer else tempfile.mkdtemp(prefix=f"mjx_surrogate_p{distributed.process_index()}_")
    )
    folder = RunFolder(out_dir, ex.name or name)
    for path in folder.recovered:
        print(f"note: recovered a run folder left unfinished by a killed process: {path}", file=sys.stderr)
    folder.write_json("config.json", to_dict(res.config))
    folder.write_text("model.xml", res.system.xml)
    folder.write_bytes("model.mjb", model_bytes(res.system.mj_model))
    folder.write_json("versions.json", versions() | {"parallel": parallel | _devices(res.system)})
    record = Run(folder, resume_from)
    key = jax.random.key(ex.seed)
    status, error = "failed", None
    guard = (
        progress.stop_on_signals()
        if threading.current_thread() is threading.main_thread()
        else contextlib.nullcontext()
    )
    progress.clear_stop()
    try:
        with guard:
            status = kinds()[ex.kind](res, record, key)
    except (Interrupted, KeyboardInterrupt) as exc:
        status, error = "interrupted", exc
    except Exception as exc:  # keep what was produced, say what happened
        status, error = "failed", exc
    finally:
        path = record.finish(status, error)
        progress.clear_stop()
    LAST_STATUS["status"] = record.metrics.get("status")
    if not writer:
        shutil.rmtree(out_dir, ignore_errors=True)
        return path
    print(summary_screen(record.metrics, path))
    return path


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


def summary_screen(metrics: dict, path: str) -> str:
    """The end-of-run summary: one line of status and costs, then per solve its cost,
    verdict, goal test, iterations and time."""
    lines = [summary_line(metrics, path)]
    for key in ("d2c", "optimum", "exact"):
        m = metrics.get(key)
        if not isinstance(m, dict) or "status" not in m:
            continue
        goal = m.get("goal") or {}
        reached = {True: "goal reached", False: "goal NOT reached"}.get(goal.get("reached"), "")
        t = m.get("run_s", m.get("wall_s"))
        lines.append(
            f"  {key:8s} {m['status']:10s} cost {m.get('cost')} ({m.get('iterations')} iterations"
            + (f", {t:.2f} s" if isinstance(t, (int, float)) else "")
            + (f", compile {m['compile_s']:.1f} s" if isinstance(m.get("compile_s"), (int, float)) else "")
            + f") {reached}"
            + (f"; goal cost {goal.get('goal_cost_start')} -> {goal.get('goal_cost_final')}" if goal else "")
        )
    return "\n".join(lines)


def summary_line(metrics: dict, path: str) -> str:
    """One line: status, the main costs, the time, the folder."""
    parts = [f"[{metrics.get('status')}]"]
    for key in ("d2c", "optimum", "exact"):
        m = metrics.get(key)
        if isinstance(m, dict) and "cost" in m:
            parts.append(f"{key} cost {m['cost']}")
    if "d2c_vs_exact_relative_gap" in metrics:
        parts.append(f"gap {100 * metrics['d2c_vs_exact_relative_gap']:.3g} %")
    if metrics.get("error"):
        parts.append(f"({metrics['error'].splitlines()[0][:200]})")
    parts.append(f"{metrics.get('wall_time_s', 0):.1f} s; run folder: {path}")
    return " ".join(parts)


def main(argv: list[str] | None = None) -> int:
    """CLI entry; exit status 0 (converged, stalled, max_iter, completed), 1 (diverged,
    failed), 2 (bad input, nothing run), 130 (interrupted)."""
    from mjx_surrogate.results import EXIT_CODES

    argv = sys.argv[1:] if argv is None else argv
    try:
        cfg, name = parse_args(argv)
        run(cfg, name)
    except ConfigError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return EXIT_CODES.get(LAST_STATUS.get("status"), 1)


if __name__ == "__main__":
    sys.exit(main())
