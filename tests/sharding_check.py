"""Run the engine's batched workloads on one device and spread over meshes; write JSON.

    python tests/sharding_check.py --process-id I --port P --result-file F [--cpu-devices 2]

Spawned twice by tests/test_sharding.py: two processes on localhost joined by
``jax.distributed``, each with 2 host CPU devices (``jax_num_cpu_devices``; a device count
is fixed when JAX starts). Each workload is computed once without a mesh (the
reference) and once on a mesh:

* "local": the process's own 2 devices (process 0: the MJX backend's sharded blocks of a
  D2C solve; process 1: the MLP seeds; the two work in parallel);
* "global": all 4 devices of both processes; the native backend (a solve, a multi-start
  solve and a data set) narrows it to one device per process
  (:func:`mjx_surrogate.sharding.one_device_per_process`).

Then, optionally, a small D2C experiment through the CLI's ``run`` over the global mesh
(process 0 writes the run folder) and a two-experiment sweep through
``experiments.reproduce --distributed`` (one experiment: process 1 has none and waits
for process 0 at the barrier). Each process writes ``--result-file`` (JSON) with, per
workload and mesh, the largest difference from the reference: a file, not stdout, where
Gloo's own connection messages can land in the middle of a line.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--process-id", type=int, required=True)
    ap.add_argument("--num-processes", type=int, default=2)
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--result-file", required=True, help="the JSON result is written here")
    ap.add_argument("--cpu-devices", type=int, default=2)
    ap.add_argument("--run-dir", default=None, help="then run a small D2C experiment writing here")
    ap.add_argument("--sweep-dir", default=None, help="then a two-experiment reproduce --distributed here")
    a = ap.parse_args()

    from mjx_surrogate.runs.config import ParallelConfig
    from mjx_surrogate.runtime import configure_runtime

    configure_runtime(x64=True, compile_cache=False)
    import jax

    from mjx_surrogate import sharding
    from mjx_surrogate.runs import distributed

    jax.config.update("jax_num_cpu_devices", a.cpu_devices)
    distributed.initialize(
        ParallelConfig(
            distributed=True,
            coordinator_address=f"localhost:{a.port}",
            num_processes=a.num_processes,
            process_id=a.process_id,
        ),
        timeout_s=60,
    )
    local = sharding.device_mesh(jax.local_devices())
    every = sharding.device_mesh(jax.devices())
    out = {
        "process": jax.process_index(),
        "processes": jax.process_count(),
        "devices": len(jax.devices()),
        "local_devices": len(jax.local_devices()),
        "results": {},
    }
    r = out["results"]
    t_start = time.perf_counter()

    def stamp(what: str) -> None:
        print(f"[{time.perf_counter() - t_start:6.1f} s] {what}", file=sys.stderr, flush=True)

    stamp("joined")
    if a.process_id == 0:  # this process's devices only: the processes need not agree
        r["mjx/local"] = mjx_blocks(local)
    else:
        r["mlp/local"] = mlp_workload(local)
        r["sindy/local"] = sindy_workload(local)
    stamp("local workloads done")
    # every process, in step; the native backend keeps one device per process
    r["native/global"] = workloads("native", every, list(PARTS))
    stamp("global workloads done")
    if a.run_dir:
        out["run_cost"] = run_experiment(a.run_dir, True)
    stamp("experiment done")
    if a.sweep_dir:
        from experiments import reproduce

        sweep = ["--quick", "--distributed", "--out", a.sweep_dir, "--report"]
        sweep += [os.path.join(a.sweep_dir, "report.md"), "--only", "theory"]
        out["sweep_status"] = reproduce.main(sweep)
    stamp("sweep done")
    with open(a.result_file + ".tmp", "w") as f:
        json.dump(out, f)
    os.replace(a.result_file + ".tmp", a.result_file)
    jax.distributed.shutdown()  # together: a process that left first would fail the other


def run_experiment(out_dir: str, distributed: bool) -> float:
    """A small D2C experiment through the CLI's ``run``; returns the cost it reports."""
    import dataclasses

    from experiments.run import LAST_STATUS, run
    from mjx_surrogate.runs.config import (
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


def workloads(backend: str, mesh, parts: list[str]) -> dict:
    """A D2C solve (15 iterations), a 3-start solve and an 11-trajectory data set around
    the reference optimum, on one device (the reference) and on ``mesh``."""
    import jax
    import jax.numpy as jnp

    from mjx_surrogate.control.d2c import solve_d2c, solve_multistart
    from mjx_surrogate.control.ilqr import ILQRParams
    from mjx_surrogate.identification import data
    from mjx_surrogate.identification.sysid import SysIdParams
    from mjx_surrogate.runs import distributed
    from mjx_surrogate.runs.config import Config, SystemConfig, TaskConfig
    from mjx_surrogate.runs.resolution import resolve
    from mjx_surrogate.sharding import size
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
        if "multistart" in parts:
            U0s = 0.3 * jax.random.normal(jax.random.key(1), (3, T, 1))
            got["multistart_costs"] = solve_multistart(
                system, task, U0s, jax.random.key(2), params, sysid
            ).costs
        if "data" in parts:
            X, U = (solve.X, solve.U) if nominal is None else nominal  # the same nominal for all
            got["dataset_X"] = data.sample(system, X, U, jax.random.key(3), 11, 0.1).X
        got = jax.device_get(got)
        print(f"{backend} on {size(mesh)} devices: {time.perf_counter() - t0:.1f} s", file=sys.stderr)
        return got

    ref = compute(None)
    distributed.barrier(f"{backend}: references done")  # into the first collective together
    got = compute(mesh, (ref["d2c_X"], ref["d2c_U"]))
    diffs = {k: _diff(got[k], ref[k]) for k in ref}
    return {
        "reference_cost": float(ref["d2c_cost"]),
        "reference_iterations": int(ref["d2c_iterations"]),
        "mesh_devices": size(make_system("pendulum", backend, mesh=mesh).mesh),
    } | diffs


def mjx_blocks(mesh) -> dict:
    """The two sharded parts of a D2C iteration on the MJX backend, and a data set: the
    LTV identification (samples spread, statistics psum-ed), the line search's trial
    rollouts (step sizes spread) and 11 perturbed trajectories (spread). Whole MJX solves
    compile for ~20 s on 2 cores; the solve's other parts are the same replicated code
    on both backends, and whole solves are checked on the native backend."""
    import jax
    import jax.numpy as jnp

    from mjx_surrogate.control.d2c import sharded_trials
    from mjx_surrogate.control.ilqr import closed_loop
    from mjx_surrogate.identification import data, sysid
    from mjx_surrogate.systems import make_system

    T, n_alphas = 30, 8
    p = sysid.SysIdParams(sigma_x=1e-6, sigma_u=1e-6, n_samples=7)

    def compute(mesh):
        system = make_system("pendulum", "mjx", mesh=mesh)
        U = 0.5 * jnp.sin(jnp.linspace(0.0, 3.0, T))[:, None]
        X = data.rollout(system.on_one_device(), jnp.zeros((1, 2)), U[None])[0]
        A, B = jax.jit(lambda X, U, k: sysid.ltv_linearize(system, p)(X, U, None, k))(X, U, jax.random.key(0))
        k = 0.1 * jnp.cos(jnp.linspace(0.0, 3.0, T))[:, None]
        K = jnp.tile(jnp.array([[-0.5, -0.1]]), (T, 1, 1))
        alphas = 0.5 ** jnp.arange(n_alphas, dtype=X.dtype)
        lo, hi = jnp.full((1,), -jnp.inf), jnp.full((1,), jnp.inf)
        if mesh is None:
            one = lambda a: closed_loop(system.step, X[0], X, U, k, K, a, lo, hi)  # noqa: E731
            trials = jax.jit(jax.vmap(one))(alphas)
        else:
            trials = jax.jit(sharded_trials(system.step, None, mesh))(X[0], X, U, k, K, alphas, lo, hi)
        ds = data.sample(system, X, U, jax.random.key(3), 11, 0.1)
        return jax.device_get(
            {"ltv_A": A, "ltv_B": B, "trials_X": trials[0], "trials_U": trials[1], "dataset_X": ds.X}
        )

    ref, got = compute(None), compute(mesh)
    return {k: _diff(got[k], ref[k]) for k in ref}


def mlp_workload(mesh) -> dict:
    """Three networks trained by ``train_seeds``, on one device and spread over ``mesh``."""
    import jax

    from mjx_surrogate.surrogates import mlp

    spec = mlp.MLPSpec(widths=(8,), batch_size=16, epochs=3)
    K, M = 3, 64
    kz, ky = jax.random.split(jax.random.key(4))
    z = jax.random.normal(kz, (K, M, 3))
    y = jax.random.normal(ky, (K, M, 2))
    keys = jax.random.split(jax.random.key(5), K)

    def compute(mesh):
        r = mlp.train_seeds(spec, keys, z, y, z[:, :16], y[:, :16], mesh=mesh)
        return jax.device_get({"test_loss": r.test_loss, "params": jax.tree.leaves(r.model.params)})

    ref, got = compute(None), compute(mesh)
    return {
        "test_loss": _diff(got["test_loss"], ref["test_loss"]),
        "params": max(_diff(g, r) for g, r in zip(got["params"], ref["params"])),
    }


def sindy_workload(mesh) -> dict:
    """A SINDy fit as the prediction study makes it (``sindy`` kind, quadratic library) on
    transitions whose rows are spread over ``mesh``, against the fit on one device: the
    coefficients' difference and the number of devices the solve's result lies on."""
    import types

    import jax
    from jax.sharding import NamedSharding, PartitionSpec

    from mjx_surrogate.runs.config import Config, SindyConfig, SurrogateConfig
    from mjx_surrogate.surrogates import registry

    nx, nu, R = 3, 1, 64
    kx, ku, kn = jax.random.split(jax.random.key(6), 3)
    x, u = jax.random.normal(kx, (R, nx)), jax.random.normal(ku, (R, nu))
    train = types.SimpleNamespace(x=x, u=u, x_next=x + 0.1 * u + 0.01 * jax.random.normal(kn, (R, nx)))
    rows = NamedSharding(mesh, PartitionSpec(mesh.axis_names[0]))
    spread = types.SimpleNamespace(**{f: jax.device_put(v, rows) for f, v in vars(train).items()})
    config = Config(surrogate=SurrogateConfig(kinds=("sindy",), sindy=SindyConfig(libraries=("poly2",))))
    ctx = registry.FitContext(config, types.SimpleNamespace(nx=nx, nu=nu, angle_pairs=()))
    ref = registry.get_surrogate("sindy").fit(ctx, train, train, None)["SINDy poly2"].model.coef
    got = registry.get_surrogate("sindy").fit(ctx, spread, spread, None)["SINDy poly2"].model.coef
    # the analysis study's variance stage: two data sets' projections against their pooled fit
    from experiments.analysis_study import pooled_projections
    from mjx_surrogate.surrogates import sindy
    from mjx_surrogate.surrogates.library import parse

    spec, ys = parse("poly2", ()), [train.x_next - train.x, 2.0 * (train.x_next - train.x)]
    D_ref, _ = pooled_projections([sindy.design(spec, train.x, train.u)] * 2, ys, "svd")
    spread_ys = [jax.device_put(y, rows) for y in ys]
    D_got, _ = pooled_projections([sindy.design(spec, spread.x, spread.u)] * 2, spread_ys, "svd")
    return {
        "coef": _diff(got, ref),
        "coef_devices": len(got.sharding.device_set),
        "projections": _diff(D_got, D_ref),
    }


if __name__ == "__main__":
    main()
