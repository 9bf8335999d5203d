"""Run the engine's batched workloads on one device and spread over meshes; print JSON.

    python tests/sharding_check.py --cpu-devices 4 --meshes 2 4
    python tests/sharding_check.py --process-id I --num-processes 2 --port P

Spawned by tests/test_sharding.py (a device count is fixed when JAX starts, so each
configuration needs its own process). Every workload is computed once without a mesh
(the reference) and once per mesh; the output holds, per workload and mesh, the largest
difference from the reference, so the test can hold it to a stated tolerance.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cpu-devices", type=int, default=1)
    ap.add_argument("--meshes", type=int, nargs="*", default=[])
    ap.add_argument("--process-id", type=int, default=None)
    ap.add_argument("--num-processes", type=int, default=1)
    ap.add_argument("--port", type=int, default=0)
    ap.add_argument("--native", nargs="*", default=list(PARTS), help="workloads on the native backend")
    ap.add_argument("--mjx", nargs="*", default=["solve", "data"], help="workloads on the MJX backend")
    ap.add_argument("--mjx-meshes", type=int, nargs="*", default=None, help="(default: --meshes)")
    ap.add_argument("--no-mlp", action="store_true")
    ap.add_argument("--run-dir", default=None, help="then run a small D2C experiment writing here")
    a = ap.parse_args()

    from mjx_surrogate.config import ParallelConfig
    from mjx_surrogate.runtime import configure_runtime

    configure_runtime(x64=True, compile_cache=False)
    import jax

    jax.config.update("jax_num_cpu_devices", a.cpu_devices)
    if a.process_id is not None:
        from mjx_surrogate import distributed

        distributed.initialize(
            ParallelConfig(
                distributed=True,
                coordinator_address=f"localhost:{a.port}",
                num_processes=a.num_processes,
                process_id=a.process_id,
            ),
            timeout_s=60,
        )
        meshes = [len(jax.devices())]
    else:
        meshes = a.meshes
    out = {"devices": len(jax.devices()), "processes": jax.process_count(), "results": {}}
    mjx_meshes = meshes if a.mjx_meshes is None else a.mjx_meshes
    for backend, parts, on in (("native", a.native, meshes), ("mjx", a.mjx, mjx_meshes)):
        if parts:
            out["results"][backend] = workloads(backend, on, parts)
    if not a.no_mlp:
        out["results"]["mlp"] = mlp_workload(meshes)
    if a.run_dir:
        out["run_cost"] = run_experiment(a.run_dir, a.process_id is not None)
    if jax.process_index() == 0:
        print("RESULT " + json.dumps(out), flush=True)
    if a.process_id is not None:
        jax.distributed.shutdown()  # together: a process that left first would fail the other


def run_experiment(out_dir: str, distributed: bool) -> float:
    """A small D2C experiment through the CLI's ``run``; returns the cost it reports."""
    import dataclasses

    from experiments.run import LAST_STATUS, run
    from mjx_surrogate.config import (
        Config,
        ExperimentConfig,
        ParallelConfig,
        SolverConfig,
        SystemConfig,
        TaskConfig,
    )

    cfg = Config(
        system=SystemConfig("pendulum", backend="native"),
        task=TaskConfig(T=30),
        solver=SolverConfig(max_iter=10),
        experiment=ExperimentConfig(
            out_dir=out_dir, x64=True, exact_oracle=False, progress=False, n_noise_trials=4
        ),
        parallel=ParallelConfig(distributed=distributed),
    )
    path = run(dataclasses.replace(cfg), "distributed_d2c")
    assert LAST_STATUS["status"] in ("converged", "stalled", "max_iter"), LAST_STATUS
    if not os.path.isdir(path):  # not the writer: its temporary folder is gone
        return float("nan")
    with open(os.path.join(path, "metrics.json")) as f:
        return json.load(f)["d2c"]["cost"]


def _diff(a, b) -> float:
    import numpy as np

    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    if a.shape != b.shape or not (np.isfinite(a) == np.isfinite(b)).all():
        return float("inf")
    return float(np.max(np.abs(np.nan_to_num(a) - np.nan_to_num(b)), initial=0.0))


PARTS = ("solve", "multistart", "data")


def workloads(backend: str, meshes: list[int], parts: list[str]) -> dict:
    """A D2C solve (15 iterations), a 3-start solve and an 11-trajectory data set around
    the reference optimum, on one device and on each mesh."""
    import jax
    import jax.numpy as jnp

    from mjx_surrogate import data, sharding
    from mjx_surrogate.config import Config, SystemConfig, TaskConfig
    from mjx_surrogate.d2c import solve_d2c, solve_multistart
    from mjx_surrogate.ilqr import ILQRParams
    from mjx_surrogate.resolution import resolve
    from mjx_surrogate.sharding import size
    from mjx_surrogate.sysid import SysIdParams
    from mjx_surrogate.systems import make_system

    params = ILQRParams(max_iter=15)
    sysid = SysIdParams(sigma_x=1e-6, sigma_u=1e-6, n_samples=7)  # 7: padded on 2 and 4 devices
    T = 30
    task = resolve(Config(SystemConfig("pendulum", backend=backend), TaskConfig(T=T)), local=True).task

    def compute(mesh, nominal=None):
        system = make_system("pendulum", backend, mesh=mesh)
        U0 = jnp.zeros((T, 1))
        t0 = time.perf_counter()
        solve = jax.block_until_ready(solve_d2c(system, task, U0, jax.random.key(0), params, sysid))
        got = {"d2c_cost": solve.cost, "d2c_X": solve.X, "d2c_U": solve.U, "d2c_iterations": solve.iterations}
        t1 = time.perf_counter()
        if "multistart" in parts:
            U0s = 0.3 * jax.random.normal(jax.random.key(1), (3, T, 1))
            multi = solve_multistart(system, task, U0s, jax.random.key(2), params, sysid)
            got["multistart_costs"] = jax.block_until_ready(multi.costs)
        t2 = time.perf_counter()
        if "data" in parts:
            X, U = (solve.X, solve.U) if nominal is None else nominal  # the same nominal for all
            got["dataset_X"] = data.sample(system, X, U, jax.random.key(3), 11, 0.1).X
        took = f"solve {t1 - t0:.1f} s, multistart {t2 - t1:.1f} s"
        print(f"{backend} mesh {size(mesh)}: {took}", file=sys.stderr)
        return got

    ref = {k: jax.device_get(v) for k, v in compute(None).items()}
    out = {"reference_cost": float(ref["d2c_cost"]), "reference_iterations": int(ref["d2c_iterations"])}
    for n in meshes:
        got = compute(sharding.device_mesh(jax.devices()[:n]), (ref["d2c_X"], ref["d2c_U"]))
        out[str(n)] = {k: _diff(jax.device_get(got[k]), ref[k]) for k in ref}
    return out


def mlp_workload(meshes: list[int]) -> dict:
    import jax

    from mjx_surrogate import sharding
    from mjx_surrogate.surrogates import mlp

    spec = mlp.MLPSpec(widths=(8,), batch_size=16, epochs=3)
    K, M = 3, 64
    kz, ky = jax.random.split(jax.random.key(4))
    z = jax.random.normal(kz, (K, M, 3))
    y = jax.random.normal(ky, (K, M, 2))
    keys = jax.random.split(jax.random.key(5), K)

    def compute(mesh):
        r = mlp.train_seeds(spec, keys, z, y, z[:, :16], y[:, :16], mesh=mesh)
        return {"test_loss": r.test_loss, "params": jax.tree.leaves(r.model.params)}

    ref = jax.device_get(compute(None))
    out = {}
    for n in meshes:
        got = jax.device_get(compute(sharding.device_mesh(jax.devices()[:n])))
        out[str(n)] = {
            "test_loss": _diff(got["test_loss"], ref["test_loss"]),
            "params": max(_diff(g, r) for g, r in zip(got["params"], ref["params"])),
        }
    return out


if __name__ == "__main__":
    main()
