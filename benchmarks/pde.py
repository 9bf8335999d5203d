"""Full-order against reduced-order D2C on the PDE black boxes, as the grid grows.

    python benchmarks/pde.py [--systems burgers allen_cahn allen_cahn2d] [--grids 64 256 1024]
                             [--methods exact full reduced] [--json out.json] [--figure f.png]
    python benchmarks/pde.py --from a.json b.json --figure f.png   # the figure of saved rows

For each PDE and grid size n (nx = n; ``allen_cahn2d``: n x n cells) one fresh process per
method solves the registered task (``burgers_damp``, ``allen_cahn_grow``; T = 50, float64,
the solver's defaults) from zero controls:

* ``exact``: iLQR with jax.jacfwd Jacobians through the JAX step (the oracle);
* ``full``: D2C, central differences, the default max(20, 2 (nx + nu)) samples per step;
* ``reduced``: RO-D2C (``sysid.scheme = "reduced"``), the default min(nx, max(16, 4 nu))
  snapshots.

``--basis``: instead, the time of the snapshot basis at each grid size (n = 32 snapshots,
T = 50): the thin SVD per t that ``sysid_reduced.snapshot_basis`` uses against the method of
snapshots' Gram eigendecomposition (S'S = W L W', V = S W L^-1/2), both jitted.

Each row: final cost, its gap to the oracle, iterations, verdict, black-box control steps
simulated (identification plus line search), wall time of the solve with compile time
apart, and the process's peak resident memory. Prints a markdown table.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def one(system_name: str, n: int, method: str) -> dict:
    from mjx_surrogate.runtime import configure_runtime

    configure_runtime(x64=True, compile_cache=False)
    import jax
    import jax.numpy as jnp

    from mjx_surrogate.control import d2c
    from mjx_surrogate.control.ilqr import ILQRParams, StopReason
    from mjx_surrogate.identification.sysid import SysIdParams
    from mjx_surrogate.progress import NO_PROGRESS
    from mjx_surrogate.runs import pipeline
    from mjx_surrogate.runs.model_defaults import default_n_samples
    from mjx_surrogate.systems import allen_cahn, burgers, registry
    from mjx_surrogate.tasks import make_task

    system = registry.make_function_system(f"{system_name}{n}")
    fields = {
        "burgers": lambda: burgers.damp_fields(n),
        "allen_cahn": lambda: allen_cahn.grow_fields(n, 8),
        "allen_cahn2d": lambda: allen_cahn.grow_fields(n * n, 9),
    }[system_name]()
    task = make_task(**fields, u_min=jnp.asarray(system.u_min), u_max=jnp.asarray(system.u_max))
    U0 = jnp.zeros((task.T, system.nu))
    params, key = ILQRParams(), jax.random.key(0)
    if method == "exact":
        args = (system, task, U0, params, NO_PROGRESS)
        fn, dyn = d2c.solve_exact, (task, U0, params, NO_PROGRESS)
        sid = None
    else:
        reduced = method == "reduced"
        sid = SysIdParams(
            scheme="reduced" if reduced else "central_difference",
            n_samples=default_n_samples(system.nx, system.nu, reduced),
        )
        args = (system, task, U0, key, params, sid, NO_PROGRESS)
        fn, dyn = d2c.solve_d2c, args[1:]
    t0 = time.perf_counter()
    compiled = fn.lower(*args).compile()
    compile_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    out = jax.block_until_ready(compiled(*dyn))
    run_s = time.perf_counter() - t0
    row = dict(
        system=system_name,
        nx=system.nx,
        method=method,
        cost=float(out.cost),
        iterations=int(out.iterations),
        verdict=StopReason(int(out.stop_reason)).verdict,
        compile_s=compile_s,
        run_s=run_s,
        peak_rss_gib=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20,
    )
    if sid is not None:
        row["n_samples"] = sid.n_samples
        row["simulated_steps"] = pipeline.simulation_metrics(out, task.T, params.n_alphas, sid)[
            "simulated_steps"
        ]
    return row


def basis_timings(grids: list[int], repeats: int = 20) -> None:
    from mjx_surrogate.runtime import configure_runtime

    configure_runtime(x64=True, compile_cache=False)
    import jax
    import jax.numpy as jnp

    from mjx_surrogate.identification.sysid_reduced import snapshot_basis

    def gram_basis(dX, tol):
        def one(S):  # S [n, nx]
            lam, W = jnp.linalg.eigh(S @ S.T)
            lam, W = lam[::-1], W[:, ::-1]
            before = jnp.cumsum(lam) - lam
            keep = (before < (1 - tol) * jnp.sum(lam)) & (lam > 0)
            return (S.T @ W) * jnp.where(keep, 1 / jnp.sqrt(jnp.where(keep, lam, 1.0)), 0.0)

        return jax.lax.map(one, jnp.swapaxes(dX, 0, 1))

    print("| nx | SVD per t (ms) | Gram eigendecomposition (ms) |")
    print("|---|---|---|")
    for n in grids:
        dX = jax.random.normal(jax.random.key(0), (32, 51, n))
        times = []
        for fn in (jax.jit(snapshot_basis), jax.jit(gram_basis)):
            jax.block_until_ready(fn(dX, 1e-8))
            t0 = time.perf_counter()
            for _ in range(repeats):
                jax.block_until_ready(fn(dX, 1e-8))
            times.append(1e3 * (time.perf_counter() - t0) / repeats)
        print(f"| {n} | {times[0]:.2f} | {times[1]:.2f} |", flush=True)


def figure(rows: list[dict], path: str) -> None:
    """Wall time (compile apart) against nx, one panel per PDE, one line per method."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    systems = sorted({r["system"] for r in rows})
    fig, axes = plt.subplots(1, len(systems), figsize=(5 * len(systems), 3.6), squeeze=False)
    for ax, system in zip(axes[0], systems):
        for method, label in (("full", "full-order D2C"), ("reduced", "RO-D2C"), ("exact", "jacfwd oracle")):
            pts = sorted(
                (r["nx"], r["run_s"]) for r in rows if r["system"] == system and r["method"] == method
            )
            if pts:
                ax.loglog(*zip(*pts), "o-", label=label)
        ax.set_xlabel("nx (grid cells)")
        ax.set_ylabel("solve wall time, s (compile apart)")
        ax.set_title(system)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--systems", nargs="+", default=["burgers", "allen_cahn"])
    ap.add_argument("--grids", nargs="+", type=int, default=[64, 256, 1024])
    ap.add_argument("--methods", nargs="+", default=["exact", "full", "reduced"])
    ap.add_argument("--json", default=None)
    ap.add_argument("--basis", action="store_true", help="time the snapshot basis only")
    ap.add_argument("--figure", default=None, help="plot time against nx (with --from: of saved rows)")
    ap.add_argument("--from", dest="saved", nargs="+", default=None, help="rows saved by --json")
    ap.add_argument("--one", nargs=3, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        print(json.dumps(one(args.one[0], int(args.one[1]), args.one[2])))
        return
    if args.basis:
        basis_timings(args.grids)
        return
    if args.saved:
        rows = [r for path in args.saved for r in json.load(open(path))]
        figure(rows, args.figure or "pde_time_vs_nx.png")
        return
    rows = []
    head = "| system | nx | method | cost | gap to oracle | iterations | verdict | simulated steps |"
    print(head + " run s | compile s | peak GiB |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for system in args.systems:
        for n in args.grids:
            oracle = None
            for method in args.methods:
                cmd = [sys.executable, __file__, "--one", system, str(n), method]
                res = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
                if res.returncode != 0:
                    print(f"| {system} | {n} | {method} | failed: {res.stderr.strip().splitlines()[-1]} |")
                    continue
                r = json.loads(res.stdout.strip().splitlines()[-1])
                rows.append(r)
                oracle = r["cost"] if method == "exact" else oracle
                gap = "" if oracle is None else f"{100 * (r['cost'] - oracle) / abs(oracle):+.2g} %"
                print(
                    f"| {system} | {r['nx']} | {method} | {r['cost']:.6g} | {gap} | {r['iterations']} | "
                    f"{r['verdict']} | {r.get('simulated_steps', '')} | {r['run_s']:.1f} | "
                    f"{r['compile_s']:.1f} | {r['peak_rss_gib']:.2f} |",
                    flush=True,
                )
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)
    if args.figure:
        figure(rows, args.figure)


if __name__ == "__main__":
    sys.path.insert(0, ROOT)
    main()
