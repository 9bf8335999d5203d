"""Time to build a 60,000-transition data set and to fit each global model, beside
pysindy's fit of the same library on the same data (cartpole swing-up, 10 % U_max).

    python benchmarks/surrogates.py [--n-traj 2000] [--epochs 200]

Compile time is reported apart from run time (AOT: lower + compile, then the call).
"""

from __future__ import annotations

import os as _os
import sys as _sys

_sys.path.insert(0, _os.path.dirname(_os.path.dirname(_os.path.abspath(__file__))))
_sys.path.insert(0, _os.path.join(_os.path.dirname(_os.path.dirname(_os.path.abspath(__file__))), "tests"))

import argparse
import time
import warnings

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--n-traj", type=int, default=2000)
    ap.add_argument("--epochs", type=int, default=200)
    a = ap.parse_args()
    import jax
    import jax.numpy as jnp

    from mjx_surrogate.runtime import configure_runtime

    configure_runtime()
    from configs import load as load_config
    from mjx_surrogate.control.d2c import solve_d2c
    from mjx_surrogate.identification import data
    from mjx_surrogate.identification.rollout import rollout
    from mjx_surrogate.runs.pipeline import initial_controls
    from mjx_surrogate.runs.resolution import resolve, solver_params
    from mjx_surrogate.surrogates import mlp, sindy
    from mjx_surrogate.surrogates.registry import library_specs

    jax.config.update("jax_enable_x64", True)
    cfg = load_config("cartpole_predict")
    _, system, task = resolve(cfg)
    params, sid = solver_params(cfg)
    U0 = initial_controls(jax.random.key(0), task.T, system.nu, "zeros", 0.0)
    opt = solve_d2c(system, task, U0, jax.random.key(1), params, sid)
    X = rollout(system, task.x0[None], opt.U[None])[0]
    rows = []

    def timed(label, fn, *args, static=()):
        jitted = jax.jit(fn, static_argnums=static)
        t0 = time.perf_counter()
        comp = jitted.lower(*args).compile()
        t1 = time.perf_counter()
        out = jax.block_until_ready(comp(*[x for i, x in enumerate(args) if i not in static]))
        rows.append((label, t1 - t0, time.perf_counter() - t1))
        return out

    ds = timed(
        f"data set ({a.n_traj} x {task.T} transitions, {system.backend})",
        lambda k: data.sample(system, X, opt.U, k, a.n_traj, 0.10),
        jax.random.key(2),
    )
    tr = data.transitions(ds)
    specs = library_specs(cfg, system)
    for name, spec in specs.items():
        theta = sindy.design(spec, tr.x, tr.u)
        timed(
            f"SINDy {name} least squares (SVD, P={theta.shape[1]})",
            lambda th, y: sindy.lstsq(th, y, "svd"),
            theta,
            tr.x_next,
        )
        timed(
            f"SINDy {name} least squares (normal equations)",
            lambda th, y: sindy.lstsq(th, y, "normal"),
            theta,
            tr.x_next,
        )
        timed(
            f"SINDy {name} STLSQ (threshold 1e-3)",
            lambda th, y: sindy.stlsq(th, y, 1e-3, 0.05, 20, True),
            theta,
            tr.x_next,
        )
    z = jnp.concatenate([tr.x, tr.u], -1)
    spec = mlp.MLPSpec(epochs=a.epochs)
    timed(
        f"MLP 32-64, {a.epochs} epochs, batch 256",
        lambda k, zz, yy: mlp.train(spec, k, zz, yy, zz[:1000], yy[:1000]).train_loss,
        jax.random.key(3),
        z,
        tr.x_next,
    )
    try:
        import pysindy as ps

        xs = np.asarray(ds.X)
        us = np.asarray(ds.U)
        lib = ps.PolynomialLibrary(degree=3) + ps.FourierLibrary(n_frequencies=1)
        for label, opt_ in (
            ("pysindy STLSQ threshold 0 (least squares)", ps.STLSQ(threshold=0.0, alpha=0.0)),
            ("pysindy STLSQ threshold 1e-3", ps.STLSQ(threshold=1e-3, alpha=0.05, normalize_columns=True)),
        ):
            model = ps.DiscreteSINDy(optimizer=opt_, feature_library=lib)
            t0 = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                model.fit([x[:-1] for x in xs], 1.0, x_next=[x[1:] for x in xs], u=list(us))
            rows.append(
                (
                    label + f" (poly3 + Fourier on all of z, P={len(model.get_feature_names())})",
                    0.0,
                    time.perf_counter() - t0,
                )
            )
    except ImportError:
        rows.append(("pysindy not installed", 0.0, float("nan")))
    print("| step | compile s | run s |\n|---|---|---|")
    for label, c, r in rows:
        print(f"| {label} | {c:.2f} | {r:.3f} |")


if __name__ == "__main__":
    main()
