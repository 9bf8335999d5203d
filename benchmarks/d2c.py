"""D2C speed and cost on the D2C 2.0 task settings, in one run:

* the jitted engine (``solve_d2c``; compile time apart from run time),
* the exact-Jacobian oracle from the same initial controls (the 1 % cost target),
* the NumPy + native ``mujoco.rollout`` reference of the same algorithm
  (``tests/reference_d2c_numpy.py``), same start, samples and stopping rules,
* the published D2C 2.0 wall times and costs (their models differ: indicative only),
* the physics rate of the D2C solve (simulated control steps x substeps / run time) against
  plain ``mujoco.rollout`` on all threads doing one-step simulations from the solution's
  states on the same model.

    python benchmarks/d2c.py [--systems pendulum cartpole fish swimmer6] [--backend auto]
                             [--max-iter N] [--rel-tol R] [--sysid SCHEME] [--n-samples N]
                             [--sigma S] [--repeats N] [--polish]
                             [--no-exact] [--no-numpy] [--solver FIELD=VALUE,...]

``--sysid``, ``--n-samples`` and ``--sigma`` override the presets' identification. The NumPy
reference uses the same scheme (central or forward differences), samples and sigma; with a
rollout scheme it falls back to central differences. ``--repeats N`` runs the compiled D2C
solve and the NumPy reference N times each and reports the median (the exact oracle once).
``--polish`` also runs the exact oracle from D2C's solution: how much exact Jacobians can
still improve it (printed after the table row). ``--solver`` sets any solver fields over the
preset's (as ``benchmarks/sample_efficiency.py``'s variants), e.g. D2C 2.0's scheme on the
fish: ``--solver sysid.design=gaussian,sysid.every=1,solver.sysid_refine_tol=0``. The NumPy
reference draws i.i.d. Gaussian samples at every step; a row whose engine scheme differs
says so in its per-iteration column.
"""

from __future__ import annotations

import os as _os
import sys as _sys

_sys.path.insert(0, _os.path.dirname(_os.path.dirname(_os.path.abspath(__file__))))
_sys.path.insert(0, _os.path.join(_os.path.dirname(_os.path.dirname(_os.path.abspath(__file__))), "tests"))

import argparse
import time

import numpy as np

PUBLISHED = {  # D2C 2.0: (LLS-CD time s, LLS-CD cost, FD time s, FD cost)
    "pendulum": (0.23, 0.626, 0.17, 0.626),
    "cartpole": (None, 9942, 1.1, 9943),
    "fish": (53.5, 401.7, 750, 373.2),
    "swimmer6": (132, 1332, 1913, 1179),
}


def bench(
    name: str,
    backend: str,
    max_iter: int | None,
    exact: bool,
    numpy_ref: bool,
    sysid: str | None = None,
    n_samples: int | None = None,
    sigma: float | None = None,
    rel_tol: float | None = None,
    repeats: int = 1,
    polish: bool = False,
    solver: str = "base",
) -> dict:
    import dataclasses

    import jax
    import reference_d2c_numpy as d2c_numpy  # the test oracle, tests/reference_d2c_numpy.py
    from sample_efficiency import with_overrides

    from configs import load as load_config
    from mjx_surrogate.control.d2c import solve_d2c, solve_exact
    from mjx_surrogate.runs.pipeline import initial_controls, simulation_metrics
    from mjx_surrogate.runs.resolution import resolve, solver_params
    from mjx_surrogate.tasks import weight_matrix
    from mjx_surrogate.timing import compile_then_run

    cfg = load_config(f"{name}_d2c")
    jax.config.update("jax_enable_x64", cfg.experiment.x64)  # the preset's precision
    cfg = dataclasses.replace(cfg, system=dataclasses.replace(cfg.system, backend=backend))
    solver_over = {k: v for k, v in dict(max_iter=max_iter, rel_tol=rel_tol).items() if v}
    sysid_over = {
        k: v for k, v in dict(scheme=sysid, n_samples=n_samples, sigma_x=sigma, sigma_u=sigma).items() if v
    }
    cfg = dataclasses.replace(
        cfg,
        solver=dataclasses.replace(cfg.solver, **solver_over),
        sysid=dataclasses.replace(cfg.sysid, **sysid_over),
    )
    if solver != "base":  # sysid.n_samples=0 means nx + nu: the model is needed
        preset_system = resolve(cfg)[1]
        cfg = with_overrides(solver, cfg, preset_system.nx + preset_system.nu)
    _, system, task = resolve(cfg)
    params, sid = solver_params(cfg)
    U0 = initial_controls(jax.random.key(0), task.T, system.nu, cfg.solver.init, cfg.solver.init_scale)
    row = {
        "system": name,
        "backend": system.backend,
        "T": task.T,
        "n_samples": sid.n_samples,
        "scheme": f"{sid.scheme} n={sid.n_samples} sigma={float(sid.sigma_x):g}"
        + ("" if sid.design == "gaussian" else f" {sid.design}")
        + ("" if sid.every == 1 else f" every {sid.every}"),
        "precision": "f64" if cfg.experiment.x64 else "f32",
    }
    options = system.compiler_options  # XLA options of this backend's programs
    t = compile_then_run(
        solve_d2c, (system,), (task, U0, jax.random.key(1), params, sid), repeats, compiler_options=options
    )
    row.update(
        d2c_cost=float(t.out.cost),
        d2c_iters=int(t.out.iterations),
        d2c_compile=t.compile_s,
        d2c_run=t.run_s,
        d2c_conv=bool(t.out.converged),
    )
    steps = simulation_metrics(t.out, task.T, params.n_alphas, sid)["simulated_steps"]
    row.update(
        physics_rate=steps * system.substeps / t.run_s,
        rollout_rate=rollout_rate(system, np.asarray(t.out.X), np.asarray(t.out.U)),
    )
    if exact:
        e = compile_then_run(solve_exact, (system,), (task, U0, params), compiler_options=options)
        row.update(
            exact_cost=float(e.out.cost),
            exact_iters=int(e.out.iterations),
            exact_compile=e.compile_s,
            exact_run=e.run_s,
        )
    if polish:
        p = compile_then_run(solve_exact, (system,), (task, t.out.U, params), compiler_options=options)
        row.update(polish_cost=float(p.out.cost), polish_iters=int(p.out.iterations))
    if numpy_ref:
        step = d2c_numpy.NativeStepper(system.mj_model, system.substeps, nthread=2)
        Q, Q_f = weight_matrix(task.Q), weight_matrix(task.Q_f)
        a = [np.asarray(v, np.float64) for v in (task.x0, task.x_goal, Q, Q_f, task.R)]
        times = []
        for _ in range(max(1, repeats)):
            t0 = time.perf_counter()
            ref = d2c_numpy.solve(
                step,
                a[0],
                np.asarray(U0, np.float64),
                *a[1:],
                seed=1,
                n_samples=sid.n_samples,
                sigma=float(sid.sigma_x),
                max_iter=params.max_iter,
                rel_tol=float(params.rel_tol),
                n_alphas=params.n_alphas,
                scheme="forward_difference" if sid.scheme == "forward_difference" else "central_difference",
            )
            times.append(time.perf_counter() - t0)
        row.update(np_run=sorted(times)[len(times) // 2], np_cost=ref["cost"], np_iters=ref["iterations"])
        # the reference draws i.i.d. Gaussian samples at every step: another scheme otherwise
        row["np_same_scheme"] = sid.design == "gaussian" and sid.every == 1
    return row


def rollout_rate(system, X: np.ndarray, U: np.ndarray, batch: int = 8192, repeats: int = 3) -> float:
    """Physics steps per second of plain ``mujoco.rollout`` on all threads for the work of
    an identification: ``batch`` one-control-step simulations from the states X [T+1, nx]
    with the controls U [T, nu] of a solution (median of ``repeats``)."""
    import os

    import mujoco
    from mujoco import rollout as mj_rollout

    m, S, nx = system.mj_model, system.substeps, system.nx
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    init = np.empty((batch, mujoco.mj_stateSize(m, spec)))
    mujoco.mj_getState(m, mujoco.MjData(m), init[0], spec)
    init[:] = init[0]
    t = np.arange(batch) % U.shape[0]
    init[:, 1 : 1 + nx] = X[t]
    ctrl = np.repeat(U[t][:, None], S, axis=1)
    datas = [mujoco.MjData(m) for _ in range(os.cpu_count() or 1)]
    times = []
    for _ in range(repeats + 1):  # the first call warms up
        t0 = time.perf_counter()
        mj_rollout.rollout(m, datas, init, ctrl)
        times.append(time.perf_counter() - t0)
    return batch * S / sorted(times[1:])[len(times[1:]) // 2]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--systems", nargs="+", default=["pendulum", "cartpole", "fish", "swimmer6"])
    ap.add_argument("--backend", default="auto", choices=["auto", "mjx", "native"])
    ap.add_argument("--max-iter", type=int, default=None)
    ap.add_argument("--rel-tol", type=float, default=None)
    ap.add_argument("--sysid", default=None, help="identification scheme (default: preset's)")
    ap.add_argument("--n-samples", type=int, default=None)
    ap.add_argument("--sigma", type=float, default=None)
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--polish", action="store_true")
    ap.add_argument("--no-exact", action="store_true")
    ap.add_argument("--no-numpy", action="store_true")
    ap.add_argument(
        "--solver",
        default="base",
        help="comma-separated solver and sysid settings over the preset's, e.g. sysid.every=1",
    )
    a = ap.parse_args()
    from mjx_surrogate.runtime import configure_runtime

    configure_runtime()

    f = lambda v, p=3: "-" if v is None else (f"{v:.{p}g}" if isinstance(v, float) else str(v))  # noqa
    print(
        "| system | backend | precision | identification | T | D2C cost | iters | D2C run s | D2C compile s "
        "| exact cost | exact iters | gap % | NumPy+native run s | NumPy cost | speed-up vs NumPy "
        "| published LLS-CD s / cost | published FD s / cost "
        "| physics steps/s | of mujoco.rollout's | speed-up vs NumPy per iteration |"
    )
    print("|" + "---|" * 20)
    for name in a.systems:
        r = bench(
            name,
            a.backend,
            a.max_iter,
            not a.no_exact,
            not a.no_numpy,
            a.sysid,
            a.n_samples,
            a.sigma,
            a.rel_tol,
            a.repeats,
            a.polish,
            a.solver,
        )
        gap = 100 * (r["d2c_cost"] - r["exact_cost"]) / abs(r["exact_cost"]) if "exact_cost" in r else None
        sp = r["np_run"] / r["d2c_run"] if "np_run" in r else None
        per_it = "-"
        if "np_run" in r:  # per iteration, as the two may stop at different counts
            per_it = f((r["np_run"] / r["np_iters"]) / (r["d2c_run"] / r["d2c_iters"]))
            per_it += f" ({r['np_iters']} iters)" + ("" if r["np_same_scheme"] else ", other scheme")
        p = PUBLISHED.get(name, (None,) * 4)
        print(
            f"| {name} | {r['backend']} | {r['precision']} | {r['scheme']} | {r['T']} | "
            f"{f(r['d2c_cost'], 5)} | "
            f"{r['d2c_iters']} | {f(r['d2c_run'])} | {f(r['d2c_compile'])} | "
            f"{f(r.get('exact_cost'), 5)} | {r.get('exact_iters', '-')} | "
            f"{f(gap, 2)} | {f(r.get('np_run'))} | {f(r.get('np_cost'), 5)} | {f(sp)} | "
            f"{f(p[0])} / {f(p[1], 4)} | {f(p[2])} / {f(p[3], 4)} | "
            f"{r['physics_rate'] / 1e6:.3g} M | {100 * r['physics_rate'] / r['rollout_rate']:.0f} % "
            f"({r['rollout_rate'] / 1e6:.3g} M) | {per_it} |",
            flush=True,
        )
        if "polish_cost" in r:
            print(
                f"  {name}: the exact oracle started from D2C's solution ({r['d2c_cost']:.6g}) "
                f"ends at {r['polish_cost']:.6g} after {r['polish_iters']} iterations "
                f"({100 * (r['polish_cost'] - r['d2c_cost']) / abs(r['d2c_cost']):+.3g} %)",
                flush=True,
            )


if __name__ == "__main__":
    main()
