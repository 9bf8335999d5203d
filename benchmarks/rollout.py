"""Rollout throughput: the project's batched rollouts (MJX and native backends) against
plain native ``mujoco.rollout`` with 1 and 2 threads, same model, batch and horizon.

    python benchmarks/rollout.py [--systems pendulum cartpole ...] [--batches 256 4096]
                                 [--T 30] [--variants]

Prints a markdown table: control steps per second, ratios against native 2 threads, and
MJX compile time apart. ``--variants`` also measures MJX with XLA's default CPU flags
(fusion emitters on) and with the constraint solver left on, each in a subprocess since
XLA flags are read once per process.
"""

from __future__ import annotations

import os as _os
import sys as _sys

_sys.path.insert(0, _os.path.dirname(_os.path.dirname(_os.path.abspath(__file__))))
_sys.path.insert(0, _os.path.join(_os.path.dirname(_os.path.dirname(_os.path.abspath(__file__))), "tests"))

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np


def measure(
    name: str, batch: int, T: int, repeats: int, constraint_off: bool = True, mjx_max_batch: int | None = None
) -> dict:
    import jax
    import jax.numpy as jnp
    import mujoco
    from mujoco import rollout as mj_rollout

    from mjx_surrogate.systems import make_system
    from mjx_surrogate.systems.registry import default_config
    from mjx_surrogate.systems.system import build_system

    out = {"system": name, "batch": batch, "T": T}
    if constraint_off:
        mjx_sys = make_system(name, backend="mjx")
    else:  # the raw model: the constraint solver runs even with nothing to solve
        d = default_config(name)
        mjx_sys = build_system(name, d.xml(), d.substeps, "mjx")
        mjx_sys.mj_model.opt.disableflags &= ~int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
        from mjx_surrogate.systems import backend_mjx

        step = backend_mjx.make_mjx_step(mjx_sys.mj_model, mjx_sys.substeps)
        object.__setattr__(mjx_sys, "rollout", backend_mjx.make_mjx_rollout(step))
    nat_sys = make_system(name, backend="native", native_threads=2)
    rng = np.random.default_rng(0)
    x0 = np.tile(np.concatenate([mjx_sys.mj_model.qpos0, np.zeros(mjx_sys.nv)]), (batch, 1))
    U = 0.3 * rng.standard_normal((batch, T, mjx_sys.nu))
    steps = batch * T

    def timeit(fn):
        ts = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            fn()
            ts.append(time.perf_counter() - t0)
        return float(np.median(ts))

    xj, uj = jnp.asarray(x0, jnp.float32), jnp.asarray(U, jnp.float32)
    if mjx_max_batch is None or batch <= mjx_max_batch:
        f = jax.jit(mjx_sys.rollout)
        t0 = time.perf_counter()
        compiled = f.lower(xj, uj).compile()
        out["mjx_compile_s"] = time.perf_counter() - t0
        compiled(xj, uj).block_until_ready()
        out["mjx"] = steps / timeit(lambda: compiled(xj, uj).block_until_ready())
    if not constraint_off:
        return out

    g = jax.jit(nat_sys.rollout)
    g(xj, uj).block_until_ready()
    out["native_backend"] = steps / timeit(lambda: g(xj, uj).block_until_ready())

    # Plain mujoco.rollout, whole physics horizon in one call (the reference).
    m = nat_sys.mj_model
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    init = np.zeros((batch, mujoco.mj_stateSize(m, spec)))
    d0 = mujoco.MjData(m)
    mujoco.mj_getState(m, d0, init[0], spec)
    init[:] = init[0]
    ctrl = np.repeat(U, nat_sys.substeps, axis=1)
    for nthread in (1, 2):
        datas = [mujoco.MjData(m) for _ in range(nthread)]
        with mj_rollout.Rollout(nthread=nthread) as r:
            r.rollout(m, datas, init, ctrl)
            out[f"native_{nthread}t"] = steps / timeit(lambda: r.rollout(m, datas, init, ctrl))
    return out


def run_subprocess(args: list[str], env_extra: dict, timeout: float = 900) -> list[dict]:
    env = dict(os.environ, **env_extra)
    try:
        res = subprocess.run(
            [sys.executable, __file__, "--json"] + args,
            env=env,
            capture_output=True,
            text=True,
            timeout=timeout,
        )
    except subprocess.TimeoutExpired:
        return [{"error": f"{' '.join(args)}: no result within {timeout:.0f} s"}]
    if res.returncode != 0:
        return [{"error": res.stderr.strip().splitlines()[-1:]}]
    return json.loads(res.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--systems", nargs="+", default=["pendulum", "cartpole", "fish", "swimmer6", "swimmer15"])
    ap.add_argument("--batches", nargs="+", type=int, default=[256, 4096])
    ap.add_argument("--T", type=int, default=30)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--variants", action="store_true")
    ap.add_argument(
        "--mjx-max-batch", type=int, default=None, help="skip MJX above this batch for systems in --slow-mjx"
    )
    ap.add_argument("--slow-mjx", nargs="*", default=["swimmer6", "swimmer15"])
    ap.add_argument("--constraint-on", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--json", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args()
    from mjx_surrogate.runtime import configure_runtime

    configure_runtime()

    common = ["--batches", *map(str, a.batches), "--T", str(a.T), "--repeats", str(a.repeats)]
    if a.json:
        cap = lambda s: a.mjx_max_batch if s in a.slow_mjx else None  # noqa: E731
        rows = [
            measure(s, b, a.T, a.repeats, not a.constraint_on, cap(s)) for s in a.systems for b in a.batches
        ]
        print(json.dumps(rows))
        return
    # One process per system: keeps XLA and MuJoCo thread pools of one system from
    # meeting the next (a combined process hung once at 0 % CPU here).
    rows = []
    for s in a.systems:
        extra = ["--mjx-max-batch", str(a.mjx_max_batch)] if a.mjx_max_batch else []
        rows += run_subprocess(["--systems", s] + common + extra, {})
    print(f"XLA_FLAGS={os.environ.get('XLA_FLAGS', '')!r}, T={a.T}, float32, steps/s = control steps/s\n")
    print(
        "| system | batch | MJX | native backend (callback) | mujoco.rollout 1t | "
        "mujoco.rollout 2t | MJX / 2t | native backend / 2t | MJX compile s |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        if "error" in r:
            print(f"| error: {r['error']} |")
            continue
        mjx = f"{r['mjx']:,.0f}" if "mjx" in r else "skipped"
        ratio = f"{r['mjx'] / r['native_2t']:.2f}" if "mjx" in r else "-"
        comp = f"{r['mjx_compile_s']:.1f}" if "mjx" in r else "-"
        print(
            f"| {r['system']} | {r['batch']} | {mjx} | {r['native_backend']:,.0f} | "
            f"{r['native_1t']:,.0f} | {r['native_2t']:,.0f} | {ratio} | "
            f"{r['native_backend'] / r['native_2t']:.2f} | {comp} |",
            flush=True,
        )
    if a.variants:
        base = [
            "--systems",
            *a.systems,
            "--batches",
            *map(str, a.batches),
            "--T",
            str(a.T),
            "--repeats",
            str(a.repeats),
        ]
        default_xla, no_disable = [], []
        for s in a.systems:
            b = ["--systems", s] + base[base.index("--batches") :]
            default_xla += run_subprocess(b, {"MJX_SURROGATE_KEEP_XLA_FLAGS": "1", "XLA_FLAGS": ""})
            no_disable += run_subprocess(b + ["--constraint-on"], {})
        print("\nMJX variants (control steps/s; compile s in brackets):\n")
        print(
            "| system | batch | project settings | XLA default flags (fusion emitters on) | "
            "constraint solver left on |"
        )
        print("|---|---|---|---|---|")
        for r, d, c in zip(rows, default_xla, no_disable):
            fmt = lambda x: (
                f"{x['mjx']:,.0f} ({x['mjx_compile_s']:.1f})"
                if "mjx" in x  # noqa
                else str(x.get("error"))
            )
            print(f"| {r['system']} | {r['batch']} | {fmt(r)} | {fmt(d)} | {fmt(c)} |")


if __name__ == "__main__":
    main()
