"""Reproduce every experiment of the paper's "Empirical Results" and write the report.

    python -m experiments.reproduce [--quick] [--out DIR] [--report PATH]

Runs the presets below in the paper's order, each into its own run folder under DIR
(default ``runs/reproduce`` or ``runs/reproduce-quick``). Resumable at the stage level: an
experiment whose finished run folder (a success status or ``diverged``) is already in DIR
is not run again; one whose newest folder ended ``failed``, ``interrupted`` or ``killed``
is run again reusing every stage that folder finished. Then
writes the report (default: ``docs/reproduction.md`` for the full size, DIR/reproduction.md
for --quick) with every figure in order, the paper's caption, what was measured and
whether the paper's claim held. ``--quick`` shrinks data sets, epochs and orders to a
CI-scale check of the whole pipeline; its numbers are not evidence. ``--distributed``
shares the experiments among processes joined by ``jax.distributed`` (docs/scaling.md).
"""

from __future__ import annotations

import argparse
import dataclasses
import glob
import json
import os
import re
import sys
import time

from experiments import report
from experiments.run import load_config, run
from mjx_surrogate.errors import ConfigError
from mjx_surrogate.runs import distributed
from mjx_surrogate.runs.config import ParallelConfig
from mjx_surrogate.runs.results import SUCCESS
from mjx_surrogate.runtime import backend_started, configure_runtime
from mjx_surrogate.systems.registry import is_function_system

EXPERIMENTS = (
    "pendulum_predict",
    "cartpole_predict",
    "fish_predict",
    "cartpole_analysis",
    "theory",
    "cartpole_control",
    "pendulum_control",
    "fish_control",
    "cartpole_horizon",
    "swimmer_horizon",
    "swimmer15_d2c",
    "burgers_ro_d2c",
    "burgers_predict",
    "pendulum_mpc",
    "cartpole_mpc",
    "lorenz_mpc",
    "gym_inverted_pendulum_mpc",
)


def quick(cfg, name: str):
    """The CI-scale version of a preset. It runs on the native backend: its programs compile
    in seconds, where MJX's take up to half a minute on 2 cores, and the quick run checks
    the pipeline, not a backend."""
    r = dataclasses.replace
    cfg = r(
        cfg,
        system=cfg.system if is_function_system(cfg.system.name) else r(cfg.system, backend="native"),
        solver=r(cfg.solver, max_iter=min(cfg.solver.max_iter, 40)),
        data=r(
            cfg.data,
            n_traj=min(cfg.data.n_traj, 40 if name.startswith("fish") else 60),
            n_seeds=min(cfg.data.n_seeds, 2),  # a control study's seeds fitted at once
        ),
        surrogate=r(
            cfg.surrogate,
            mlp=r(
                cfg.surrogate.mlp,
                epochs=2,
                batch_size=64,
                checkpoints=(),
                fixed_epochs_beside=min(cfg.surrogate.mlp.fixed_epochs_beside, 2),
            ),
        ),
        analysis=r(
            cfg.analysis,
            n_datasets=2,
            gram_points=64,
            theory_max_order=4,
            theory_mc_samples=200,
            theory_mc_trials=40,
        ),
        experiment=r(cfg.experiment, progress=False, video=False),
    )
    if name.startswith("fish") or name in ("swimmer_horizon", "swimmer15_d2c"):
        cfg = r(cfg, task=r(cfg.task, T=60))
    if name in ("pendulum_predict", "cartpole_predict"):
        cfg = r(cfg, data=r(cfg.data, levels=(0.1, 0.6)))
    if name.endswith("_predict"):  # one SINDy library of the preset's
        sindy = cfg.surrogate.sindy
        cfg = r(cfg, surrogate=r(cfg.surrogate, sindy=r(sindy, libraries=sindy.libraries[:1])))
    if name.startswith("burgers"):  # a coarser grid: 32 cells, nx + nu = 40
        cfg = r(cfg, system=r(cfg.system, name="burgers32"), data=r(cfg.data, levels=(0.05, 0.6)))
    if name.endswith("_control"):  # the exact oracle's compile (the longest) is left to full runs
        sindy = cfg.surrogate.sindy
        cfg = r(
            cfg,
            data=r(cfg.data, levels=(0.05,)),
            experiment=r(cfg.experiment, exact_oracle=False),
            surrogate=r(cfg.surrogate, sindy=r(sindy, libraries=sindy.libraries[:1])),
            # and the random starts, judged against that oracle (tests/test_control_study.py)
            extensions={**cfg.extensions, "experiment.control": {"starts": 0}},
        )
    if cfg.experiment.kind == "mpc":  # one short condition, one episode, the verdict's controllers
        m = cfg.mpc
        cfg = r(
            cfg,
            mpc=r(
                m,
                controllers=("d2c", "tvlqr", "surrogates"),
                refit_weight=0.0,
                horizon=8 if m.horizon is None else min(m.horizon, 8),
                steps=10 if m.steps is None else min(m.steps, 10),
                max_iter=2,
                process_noise=m.process_noise[-1:],
                plants=m.plants[-1:],
                n_episodes=1,
            ),
            experiment=r(cfg.experiment, exact_oracle=False),
            surrogate=r(
                cfg.surrogate, sindy=r(cfg.surrogate.sindy, libraries=cfg.surrogate.sindy.libraries[:1])
            ),
        )
    return cfg


DONE = SUCCESS + ("diverged",)


def _status(path: str) -> str | None:
    try:
        with open(os.path.join(path, "metrics.json")) as f:
            return json.load(f).get("status")
    except (OSError, ValueError):
        return None


def _folders(out: str, name: str) -> list[str]:
    """Run folders of experiment ``name`` in ``out``, newest first: DATE-TIME_NAME or
    DATE-TIME_NAME_K, never another experiment whose name ends with it (pendulum_mpc is
    not gym_inverted_pendulum_mpc)."""
    exact = re.compile(rf"^\d{{8}}-\d{{6}}_{re.escape(name)}(_\d+)?$")
    paths = glob.glob(os.path.join(out, f"*_{name}*"))
    return sorted((p for p in paths if exact.match(os.path.basename(p))), reverse=True)


def finished(out: str, name: str) -> str | None:
    """The newest finished run folder of ``name`` in ``out``, if any."""
    for path in _folders(out, name):
        if _status(path) in DONE:
            return path
    return None


def unfinished(out: str, name: str) -> str | None:
    """The newest folder of ``name`` if it ended early (its stages can be resumed)."""
    paths = _folders(out, name)
    if paths and _status(paths[0]) in ("failed", "interrupted", "killed"):
        return paths[0]
    return None


def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="CI-scale sizes")
    ap.add_argument("--out", default=None, help="folder of the run folders")
    ap.add_argument("--report", default=None, help="path of the report (markdown)")
    ap.add_argument(
        "--only",
        nargs="*",
        default=None,
        choices=EXPERIMENTS,
        metavar="NAME",
        help="subset of: " + ", ".join(EXPERIMENTS),
    )
    ap.add_argument(
        "--distributed",
        action="store_true",
        help="share the experiments among the processes started with this same command\n"
        "(jax.distributed; rendezvous from JAX_COORDINATOR_ADDRESS, JAX_NUM_PROCESSES and\n"
        "JAX_PROCESS_ID, or the cluster's environment); process 0 writes the report",
    )
    ap.add_argument(
        "--cpu-devices",
        type=int,
        default=None,
        metavar="N",
        help="split the host CPU into N JAX devices (jax_num_cpu_devices), so that every\n"
        "experiment spreads its batches over them (docs/scaling.md); a CPU device runs a\n"
        "vmapped program mostly on one core. Must come before JAX starts its backend.",
    )
    return ap


def _split_cpu(n: int | None) -> int:
    """Split the host CPU into n JAX devices; 2 (and a line on stderr) if that cannot be done."""
    if n is None:
        return 0
    if n < 1:
        print(f"error: --cpu-devices: must be >= 1, got {n}", file=sys.stderr)
        return 2
    if backend_started():
        print("error: --cpu-devices: the JAX backend has already started in this process", file=sys.stderr)
        return 2
    import jax

    jax.config.update("jax_num_cpu_devices", n)
    return 0


def _run_experiments(
    a: argparse.Namespace, out: str, names: list[str], mine: list[str], times: dict, timing_file: str
) -> int:
    """Run this process's share of ``names`` that is not finished yet (resuming unfinished
    ones), recording each one's wall time in ``timing_file``; 130 if one was interrupted."""
    for i, name in enumerate(names, 1):
        if name not in mine:
            continue
        done = finished(out, name)
        if done:
            print(f"[{i}/{len(names)}] {name}: done already ({done})", flush=True)
            continue
        resume = unfinished(out, name)
        print(
            f"[{i}/{len(names)}] {name}: " + (f"resuming the stages of {resume}" if resume else "running"),
            flush=True,
        )
        cfg = load_config(name)
        cfg = quick(cfg, name) if a.quick else cfg
        cfg = dataclasses.replace(cfg, experiment=dataclasses.replace(cfg.experiment, out_dir=out))
        t0 = time.perf_counter()
        path = run(cfg, name, resume_from=resume, local=a.distributed, hard_stop=True)
        if _status(path) == "interrupted":
            print("interrupted: run the same command again to resume", flush=True)
            return 130
        times[name] = time.perf_counter() - t0
        with open(timing_file + ".tmp", "w") as f:
            json.dump(times, f, indent=1)
        os.replace(timing_file + ".tmp", timing_file)
    return 0


def _write_report(a: argparse.Namespace, out: str, times: dict, wall: float) -> tuple[str, dict]:
    """Render the report of the finished run folders; its path and the folders."""
    folders = {n: finished(out, n) for n in EXPERIMENTS}
    path = a.report or (
        os.path.join(out, "reproduction.md") if a.quick else os.path.join("docs", "reproduction.md")
    )
    fig_dir = os.path.join(os.path.dirname(path) or ".", "figures" if not a.quick else "report_figures")
    if os.path.isdir(fig_dir) and not a.quick:  # the report's own figures, NAME__FILE; others stay
        for old in glob.glob(os.path.join(fig_dir, "*__*")):
            os.remove(old)
    text = report.render(folders, times, fig_dir, os.path.dirname(path) or ".", a.quick, wall)
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        f.write(text)
    os.replace(tmp, path)
    return path, folders


def main(argv: list[str] | None = None) -> int:
    a = _parser().parse_args(argv)
    if code := _split_cpu(a.cpu_devices):
        return code
    out = a.out or os.path.join("runs", "reproduce-quick" if a.quick else "reproduce")
    os.makedirs(out, exist_ok=True)
    names = a.only or list(EXPERIMENTS)
    if a.distributed:
        configure_runtime()
        try:
            distributed.initialize(ParallelConfig(distributed=True))
        except ConfigError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
    configure_runtime()  # the report records the runtime flags, even when nothing is run
    mine = distributed.my_share(names) if a.distributed else names
    t_start = time.perf_counter()
    suffix = f"-p{distributed.process_index()}" if a.distributed and distributed.process_count() > 1 else ""
    timing_file = os.path.join(out, f"wall_times{suffix}.json")
    times = json.load(open(timing_file)) if os.path.exists(timing_file) else {}
    if code := _run_experiments(a, out, names, mine, times, timing_file):
        return code
    if a.distributed:
        distributed.barrier("reproduce: every experiment finished")
        if not distributed.is_writer():
            return 0
        for other in sorted(glob.glob(os.path.join(out, "wall_times-p*.json"))):
            times |= json.load(open(other))
    path, folders = _write_report(a, out, times, time.perf_counter() - t_start)
    print(f"report: {path}")
    missing = [n for n in names if folders.get(n) is None]
    return 1 if missing else 0


if __name__ == "__main__":
    sys.exit(main())
