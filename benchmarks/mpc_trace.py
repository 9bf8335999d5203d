"""Tracing, lowering and compile time of an MPC study's episode batch (compile apart from run).

The program of ``reproduce --quick``'s MPC presets: ``vmap`` over ``--episodes`` keys of one
episode of a planner (``mpc.receding_horizon`` for "d2c", ``mpc.surrogate_mpc`` on a
linear SINDy model fitted to 50 random transitions for "surrogate"), float64, on the native backend. Each
repeat starts from empty JAX caches; prints the median of each phase and the result's
hash (equal hashes: the same numbers).

    python benchmarks/mpc_trace.py [--preset pendulum_mpc] [--planner d2c] [--repeats 5]
                                   [--repo PATH]

``--repo``: the checkout whose code is imported (default: this one). This machine's speed
drifts within minutes, so compare two checkouts by alternating runs (A B B A)."""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import os
import statistics
import sys
import time


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preset", default="pendulum_mpc")
    ap.add_argument("--planner", choices=("d2c", "surrogate"), default="d2c")
    ap.add_argument("--episodes", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--repo", default=os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    a = ap.parse_args(argv)
    sys.path.insert(0, os.path.abspath(a.repo))

    from mjx_surrogate.runtime import configure_runtime

    configure_runtime(x64=True, compile_cache=False)
    import jax
    import jax.numpy as jnp
    import numpy as np

    from experiments import reproduce
    from experiments.run import load_config
    from mjx_surrogate.control import mpc
    from mjx_surrogate.runs.resolution import mpc_params, resolve

    cfg, system, task = resolve(reproduce.quick(load_config(a.preset), a.preset))
    m = cfg.mpc
    params, sysid = mpc_params(cfg)
    plan_task = dataclasses.replace(task, T=m.horizon)
    U0 = jnp.zeros((m.horizon, system.nu))
    keys = jax.random.split(jax.random.key(cfg.experiment.seed), a.episodes)
    if a.planner == "d2c":
        one = lambda k: mpc.receding_horizon(  # noqa: E731
            system, plan_task, U0, key=k, steps=m.steps, params=params, sysid=sysid, process_noise=0.01
        )
    else:
        from mjx_surrogate.surrogates.library import LibrarySpec
        from mjx_surrogate.surrogates.sindy import fit

        Z = np.random.default_rng(0).normal(size=(50, system.nx + system.nu))
        x, u = jnp.asarray(Z[:, : system.nx]), jnp.asarray(Z[:, system.nx :])
        model = fit(LibrarySpec(degree=1), x, u, jax.vmap(system.step)(x, u))
        one = lambda k: mpc.surrogate_mpc(  # noqa: E731
            model, plan_task, U0, plant=system, key=k, steps=m.steps, params=params, process_noise=0.01
        )
    times = {"trace": [], "lower": [], "compile": []}
    digest = None
    for _ in range(a.repeats):
        jax.clear_caches()
        f = jax.jit(lambda keys: jax.vmap(one)(keys))
        t0 = time.perf_counter()
        traced = f.trace(keys)
        t1 = time.perf_counter()
        lowered = traced.lower()
        t2 = time.perf_counter()
        compiled = lowered.compile()
        t3 = time.perf_counter()
        for name, t in zip(times, (t1 - t0, t2 - t1, t3 - t2)):
            times[name].append(t)
        r = compiled(keys)
        digest = hashlib.sha1(b"".join(np.asarray(v).tobytes() for v in (r.X, r.U, r.plan_cost))).hexdigest()
    med = {k: statistics.median(v) for k, v in times.items()}
    print(
        f"{a.preset} {a.planner}, {a.episodes} episodes, median of {a.repeats}: "
        + ", ".join(f"{k} {v:.2f} s" for k, v in med.items())
        + f"; result {digest[:12]}"
    )


if __name__ == "__main__":
    main()
