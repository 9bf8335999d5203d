"""Throughput against the number of devices the batch axes are spread over.

    python benchmarks/scaling.py [--devices 1 2 4] [--system cartpole] [--repeats 3]

For each device count a fresh process is started (JAX fixes its device count at start:
``jax_num_cpu_devices`` host devices on a CPU-only machine; on an accelerator machine the
first n accelerators), which measures on both backends, compile time apart:

* identification: one central-difference LTV identification of the whole horizon
  (2 n T one-step simulations, the samples spread over the devices);
* multi-start D2C: S solves of a fixed number of iterations, the starts spread;
* data set: N perturbed rollouts of the horizon, the trajectories spread.

Prints a markdown table: control steps per second, speed-up and efficiency (speed-up per
device) against one device, and the compile time. On host CPU devices all devices share
the machine's cores, so the figures show the overhead of sharding, not a speed-up.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _timed(fn, repeats: int) -> tuple[float, float]:
    """(first call incl. compile, best of ``repeats`` later calls) in seconds."""
    import jax

    t0 = time.perf_counter()
    jax.block_until_ready(fn())
    first = time.perf_counter() - t0
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(fn())
        best = min(best, time.perf_counter() - t0)
    return first, best


def child(args) -> None:
    from mjx_surrogate.runtime import configure_runtime

    configure_runtime(compile_cache=False)
    import jax

    jax.config.update("jax_num_cpu_devices", args.n)  # before the backend starts; no effect on GPUs
    import jax.numpy as jnp

    from mjx_surrogate import sharding
    from mjx_surrogate.control.d2c import solve_multistart
    from mjx_surrogate.control.ilqr import ILQRParams
    from mjx_surrogate.identification import data, sysid
    from mjx_surrogate.runs.config import Config, SystemConfig, TaskConfig
    from mjx_surrogate.runs.resolution import resolve
    from mjx_surrogate.systems import make_system

    devices = jax.devices()[: args.n]
    mesh = sharding.device_mesh(devices)
    rows = []
    for backend in ("mjx", "native"):
        sc, tc = SystemConfig(args.system, backend=backend), TaskConfig(preset=f"{args.system}_d2c")
        res = resolve(Config(system=sc, task=tc), local=True)
        task, T = res.task, int(res.config.task.T)
        system = make_system(args.system, backend, native_threads=args.threads, mesh=mesh)
        nu = system.nu
        p = sysid.SysIdParams(n_samples=args.samples)
        X = jnp.tile(task.x0, (T + 1, 1))
        U = jnp.zeros((T, nu))
        ident = jax.jit(lambda X, U, k: sysid.ltv_linearize(system, p)(X, U, None, k))
        first, best = _timed(lambda: ident(X, U, jax.random.key(0)), args.repeats)
        rows.append(("identification", backend, 2 * args.samples * T / best, first - best))
        params = ILQRParams(max_iter=args.iterations, rel_tol=0.0, k_tol=0.0)
        U0s = 0.1 * jax.random.normal(jax.random.key(1), (args.starts, T, nu))
        first, best = _timed(lambda: solve_multistart(system, task, U0s, jax.random.key(2), params, p), 1)
        per_iter = (2 * args.samples * T + params.n_alphas * T) * args.starts * args.iterations
        rows.append(("multi-start D2C", backend, per_iter / best, first - best))
        x0 = jnp.tile(task.x0, (args.trajectories, 1))
        Ud = 0.1 * jax.random.normal(jax.random.key(3), (args.trajectories, T, nu))
        roll = jax.jit(lambda x0, U: data.rollout(system, x0, U))
        first, best = _timed(lambda: roll(x0, Ud), args.repeats)
        rows.append(("data set", backend, args.trajectories * T / best, first - best))
    info = {"n": args.n, "platform": devices[0].platform, "device": str(devices[0].device_kind), "rows": rows}
    print("RESULT " + json.dumps(info), flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--devices", type=int, nargs="*", default=[1, 2, 4])
    ap.add_argument("--system", default="cartpole")
    ap.add_argument("--samples", type=int, default=20, help="identification samples per time step")
    ap.add_argument("--starts", type=int, default=8)
    ap.add_argument("--iterations", type=int, default=10)
    ap.add_argument("--trajectories", type=int, default=1024)
    ap.add_argument("--threads", type=int, default=None, help="native threads per process (None: all cores)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--child", type=int, default=None, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.child is not None:
        a.n = a.child
        child(a)
        return
    results = {}
    for n in a.devices:
        cmd = [sys.executable, os.path.abspath(__file__), "--child", str(n)] + [
            f"--{k}={v}" for k, v in vars(a).items() if k not in ("devices", "child") and v is not None
        ]
        proc = subprocess.run(
            cmd,
            capture_output=True,
            text=True,
            env=dict(
                os.environ, PYTHONPATH=os.pathsep.join(filter(None, [ROOT, os.environ.get("PYTHONPATH")]))
            ),
        )
        lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")]
        if not lines:
            sys.exit(f"{n} devices failed:\n{proc.stderr[-2000:]}")
        results[n] = json.loads(lines[-1][7:])
    first = results[a.devices[0]]
    print(f"{a.system}; {first['platform']} ({first['device']}); compile apart\n")
    print("| workload | backend | devices | control steps/s | speed-up | efficiency | compile s |")
    print("|---|---|---|---|---|---|---|")
    for i, (work, backend, _, _) in enumerate(first["rows"]):
        base = first["rows"][i][2]
        for n in a.devices:
            _, _, rate, compile_s = results[n]["rows"][i]
            s = rate / base
            eff = s / n * a.devices[0]
            print(f"| {work} | {backend} | {n} | {rate:,.0f} | {s:.2f} | {eff:.2f} | {compile_s:.1f} |")


if __name__ == "__main__":
    main()
