"""Which LTV identification scheme works where.

For each system (D2C 2.0 task settings) and scheme (central differences, open-loop
rollouts as in the paper, closed-loop rollouts under the current gains):

* the relative Frobenius error of [A_t B_t] against ``jax.jacfwd`` through MJX, along the
  exact oracle's optimal trajectory (median and max over t);
* the cost D2C reaches with that scheme from the oracle's initial controls, against the
  oracle's cost.

    python benchmarks/sysid_schemes.py [--systems pendulum cartpole] [--n-samples 25]
"""

from __future__ import annotations

import os as _os
import sys as _sys

_sys.path.insert(0, _os.path.dirname(_os.path.dirname(_os.path.abspath(__file__))))
_sys.path.insert(0, _os.path.join(_os.path.dirname(_os.path.dirname(_os.path.abspath(__file__))), "tests"))

import argparse
import dataclasses

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--systems", nargs="+", default=["pendulum", "cartpole"])
    ap.add_argument("--n-samples", type=int, default=25)
    ap.add_argument("--sigma", type=float, default=1e-3)
    ap.add_argument("--backend", default="native")
    a = ap.parse_args()
    import jax

    from mjx_surrogate.runtime import configure_runtime

    configure_runtime()
    from configs import load as load_config
    from mjx_surrogate.control.d2c import exact_linearize, solve_d2c, solve_exact
    from mjx_surrogate.control.ilqr import StopReason
    from mjx_surrogate.identification.sysid import SCHEMES, ltv_linearize
    from mjx_surrogate.linalg import ltv_relative_error
    from mjx_surrogate.runs.pipeline import initial_controls
    from mjx_surrogate.runs.resolution import resolve, solver_params

    print(f"n_samples={a.n_samples}, sigma={a.sigma}, float32, backend={a.backend}\n")
    print("| system | scheme | LTV rel. error median | max | D2C cost | exact cost | gap % | iters | stop |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name in a.systems:
        cfg = load_config(f"{name}_d2c")
        cfg = dataclasses.replace(cfg, system=dataclasses.replace(cfg.system, backend=a.backend))
        _, system, task = resolve(cfg)
        params, _ = solver_params(cfg)
        U0 = initial_controls(jax.random.key(0), task.T, system.nu, cfg.solver.init, cfg.solver.init_scale)
        ex = solve_exact(system, task, U0, params)
        Ae, Be = jax.jit(exact_linearize(system))(ex.X, ex.U, ex.K, jax.random.key(0))
        for scheme in SCHEMES:
            sid = dataclasses.replace(
                solver_params(cfg)[1], scheme=scheme, n_samples=a.n_samples, sigma_x=a.sigma, sigma_u=a.sigma
            )
            A, B = jax.jit(ltv_linearize(system, sid))(ex.X, ex.U, ex.K, jax.random.key(1))
            rel = np.asarray(ltv_relative_error(A, B, Ae, Be))
            r = solve_d2c(system, task, U0, jax.random.key(2), params, sid)
            gap = 100 * (float(r.cost) - float(ex.cost)) / abs(float(ex.cost))
            print(
                f"| {name} | {scheme} | {np.median(rel):.2e} | {np.max(rel):.2e} | "
                f"{float(r.cost):.5g} | {float(ex.cost):.5g} | {gap:.2f} | {int(r.iterations)} | "
                f"{StopReason(int(r.stop_reason)).description} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
