"""Several MLP seeds on CPU: in lockstep (``vmap``) against one after another (``lax.map``,
what :func:`mjx_surrogate.surrogates.mlp.train_seeds` does on CPU devices), compile apart.

    python benchmarks/mlp_seeds.py [--preset cartpole_control] [--seeds 5] [--level 0.05]

The preset's system and task, its D2C optimum, and ``--seeds`` data sets of
``data.n_traj`` perturbed trajectories at ``--level`` of U_max (keys 10, 11, ...), each
split 80/10/10 into training, validation and test sets; the preset's MLP
(``surrogates.registry.mlp_spec``) trained on them both ways. Prints the run seconds (best of 2), every seed's
stopping epoch and its best test loss: a vmapped ``while_loop`` runs every seed's masked
epochs until the last one stops.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from functools import partial

_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, _ROOT)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preset", default="cartpole_control")
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--level", type=float, default=0.05)
    a = ap.parse_args()
    if a.seeds < 2 or not 0 < a.level <= 1:
        ap.error("--seeds >= 2, --level in (0, 1]")

    from mjx_surrogate.runtime import configure_runtime

    configure_runtime(x64=True)
    import jax
    import jax.numpy as jnp
    import numpy as np

    from configs import load as load_config
    from mjx_surrogate.control.d2c import solve_d2c
    from mjx_surrogate.identification import data
    from mjx_surrogate.runs.pipeline import initial_controls
    from mjx_surrogate.runs.resolution import resolve, solver_params
    from mjx_surrogate.surrogates import mlp
    from mjx_surrogate.surrogates.registry import mlp_spec

    cfg = load_config(a.preset)
    _, system, task = resolve(cfg)
    params, sid = solver_params(cfg)
    U0 = initial_controls(jax.random.key(0), task.T, system.nu, "zeros", 0.0)
    opt = solve_d2c(system, task, U0, jax.random.key(1), params, sid)
    sets = {name: [] for name in ("z", "y", "z_test", "y_test", "z_val", "y_val")}
    for k in range(a.seeds):
        ds = data.sample(system, opt.X, opt.U, jax.random.key(10 + k), cfg.data.n_traj, a.level)
        tr = data.transitions(ds)
        z, y = np.concatenate([tr.x, tr.u], -1), np.asarray(tr.x_next)
        i = np.random.default_rng(k).permutation(len(z))
        cut = [int(0.8 * len(z)), int(0.9 * len(z))]
        for name, part in zip(("", "_val", "_test"), np.split(i, cut)):
            sets["z" + name].append(z[part])
            sets["y" + name].append(y[part])
    args = [jnp.asarray(np.stack(sets[n])) for n in ("z", "y", "z_test", "y_test", "z_val", "y_val")]
    spec = mlp_spec(cfg)
    keys = jax.random.split(jax.random.key(3), a.seeds)
    ways = {
        "lockstep (vmap)": jax.jit(lambda *x: jax.vmap(partial(mlp.train, spec))(*x)),
        "one after another (lax.map)": jax.jit(lambda *x: jax.lax.map(lambda t: mlp.train(spec, *t), x)),
    }
    n_train = args[0].shape[1]
    print(f"{a.preset}: {a.seeds} data sets of {n_train} training transitions, {spec.epochs} epochs at most")
    print("| way | run s | stopping epochs | best test loss |\n|---|---|---|---|")
    for way, fn in ways.items():
        compiled = fn.lower(keys, *args).compile()
        best = float("inf")
        for _ in range(2):
            t0 = time.perf_counter()
            out = jax.block_until_ready(compiled(keys, *args))
            best = min(best, time.perf_counter() - t0)
        epochs = ", ".join(str(int(e)) for e in np.asarray(out.epochs_run))
        losses = ", ".join(f"{v:.4g}" for v in np.nanmin(np.asarray(out.test_loss), axis=1))
        print(f"| {way} | {best:.1f} | {epochs} | {losses} |")


if __name__ == "__main__":
    main()
