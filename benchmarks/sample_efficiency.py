"""Black-box simulations to the optimum: the D2C 2.0 scheme against sample-efficient variants.

For each system's D2C 2.0 preset (``{system}_d2c``) and each variant (solver settings
over the preset's), one D2C solve from the preset's initial controls, same key for all:
final cost, iterations, identifications, simulated control steps, and the steps until the
cost first came within 1 % and 0.1 % of the first variant's final cost (machine
independent). Wall time is printed too (compile apart); ``--time-to-target`` solves again,
stopped at the iteration that first came within 0.1 % of the first variant's cost, and
times that solve.

A variant is ``base`` (the preset as it is) or comma-separated ``section.field=value``
settings of the solver and sysid sections, e.g. ``sysid.every=2`` or
``solver.reuse_tol=0.2,solver.reuse_max=4`` or
``sysid.scheme=forward_difference,sysid.design=orthogonal,sysid.n_samples=0`` (0: nx + nu).

    python benchmarks/sample_efficiency.py [--systems cartpole fish swimmer6]
        [--variants base sysid.every=2 ...] [--keys 1 2 3] [--figure PATH] [--x64]
"""

from __future__ import annotations

import os as _os
import sys as _sys

_sys.path.insert(0, _os.path.dirname(_os.path.dirname(_os.path.abspath(__file__))))

import argparse
import dataclasses

import numpy as np


def with_overrides(variant: str, cfg, nx_nu: int):
    """``cfg`` with variant ``base`` (none) or comma-separated ``section.field=value``
    settings of sections solver and sysid (``sysid.n_samples=0``: nx + nu)."""
    if variant == "base":
        return cfg
    for item in variant.split(","):
        dotted, value = item.split("=")
        section, name = dotted.split(".")
        if section not in ("solver", "sysid"):
            raise SystemExit(f"{dotted}: a solver.<field> or sysid.<field> setting")
        old = getattr(getattr(cfg, section), name)
        kind = type(old) if old is not None else (float if name.startswith("sigma") else int)
        v = kind(value) if kind is not bool else value == "true"
        v = nx_nu if (dotted == "sysid.n_samples" and v == 0) else v
        cfg = dataclasses.replace(cfg, **{section: dataclasses.replace(getattr(cfg, section), **{name: v})})
    return cfg


def solve(name: str, variant: str, key: int = 1, max_iter: int | None = None, x64: bool = False) -> dict:
    import jax

    from configs import load as load_config
    from mjx_surrogate.control.d2c import solve_d2c
    from mjx_surrogate.runs.pipeline import initial_controls, simulation_curve, steps_per_identification
    from mjx_surrogate.runs.resolution import resolve, solver_params
    from mjx_surrogate.timing import compile_then_run

    cfg = load_config(f"{name}_d2c")
    if x64:
        cfg = dataclasses.replace(cfg, experiment=dataclasses.replace(cfg.experiment, x64=True))
    jax.config.update("jax_enable_x64", cfg.experiment.x64)
    _, system, _ = resolve(cfg)
    cfg = with_overrides(variant, cfg, system.nx + system.nu)
    if max_iter is not None:
        cfg = dataclasses.replace(cfg, solver=dataclasses.replace(cfg.solver, max_iter=max_iter))
    _, system, task = resolve(cfg)
    params, sid = solver_params(cfg)
    U0 = initial_controls(jax.random.key(0), task.T, system.nu, cfg.solver.init, cfg.solver.init_scale)
    t = compile_then_run(
        solve_d2c,
        (system,),
        (task, U0, jax.random.key(key), params, sid),
        compiler_options=system.compiler_options,
    )
    r = t.out
    curve = simulation_curve(
        r.identified, r.iterations, task.T, params.n_alphas, *steps_per_identification(sid, task.T)
    )
    return {
        "cost": float(r.cost),
        "iterations": int(r.iterations),
        "identifications": int(np.count_nonzero(np.asarray(r.identified))),
        "stop": int(r.stop_reason),
        "curve": curve,
        "costs": np.asarray(r.cost_history)[: curve.size],
        "compile_s": t.compile_s,
        "run_s": t.run_s,
    }


def steps_to(res: dict, target: float, rel: float) -> int | None:
    i = iteration_to(res, target, rel)
    return None if i is None else int(res["curve"][i])


def iteration_to(res: dict, target: float, rel: float) -> int | None:
    hit = np.nonzero(res["costs"] <= target + rel * abs(target))[0]
    return int(hit[0]) if len(hit) else None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--systems", nargs="+", default=["cartpole", "fish", "swimmer6"])
    ap.add_argument("--variants", nargs="+", default=["base", "sysid.every=2"])
    ap.add_argument("--keys", nargs="+", type=int, default=[1], help="identification keys (a row each)")
    ap.add_argument(
        "--time-to-target",
        action="store_true",
        help="solve again, stopped at the iteration that reached 0.1 %% of the first's cost, and time it",
    )
    ap.add_argument("--figure", default=None, help="write cost against simulated steps here")
    ap.add_argument("--x64", action="store_true", help="every preset in float64 (e.g. the float32 cartpole)")
    a = ap.parse_args()
    from mjx_surrogate.control.ilqr import StopReason
    from mjx_surrogate.runtime import configure_runtime

    configure_runtime()
    print(
        "| system | variant | cost | vs first | stop | iterations | identifications | simulated steps | "
        "to 1 % of first's | to 0.1 % | x fewer (0.1 %) | run s | run s to 0.1 % |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    curves = {}
    for name, key in [(n, k) for n in a.systems for k in a.keys]:
        base = None
        for v in a.variants:
            r = solve(name, v, key, x64=a.x64)
            base = base or r
            J = base["cost"]
            s1, s01 = steps_to(r, J, 1e-2), steps_to(r, J, 1e-3)
            b01 = steps_to(base, J, 1e-3)
            ratio = f"{b01 / s01:.2f}" if s01 and b01 else "-"
            label = v if len(a.keys) == 1 else f"{v} (key {key})"
            hit = iteration_to(r, J, 1e-3)
            to_s = "-"
            if a.time_to_target and hit:
                to_s = f"{solve(name, v, key, max_iter=hit, x64=a.x64)['run_s']:.2f}"
            print(
                f"| {name} | {label} | {r['cost']:.6g} | {(r['cost'] - J) / abs(J):+.2e} | "
                f"{StopReason(r['stop']).verdict} | {r['iterations']} | {r['identifications']} | "
                f"{int(r['curve'][-1])} | {s1} | {s01} | {ratio} | {r['run_s']:.1f} | {to_s} |",
                flush=True,
            )
            if key == a.keys[0]:
                curves[(name, v)] = (r["curve"], r["costs"])
    if a.figure:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(1, len(a.systems), figsize=(4.6 * len(a.systems), 3.6), squeeze=False)
        for ax, name in zip(axes[0], a.systems):
            J = min(np.nanmin(c[1]) for (n, _), c in curves.items() if n == name)
            for (n, v), (x, y) in curves.items():
                if n == name:
                    ax.plot(x, np.maximum(y - J, 1e-12 * abs(J)) / abs(J), label=v)
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_title(name)
            ax.set_xlabel("simulated control steps")
            ax.set_ylabel("(J - J_best) / |J_best|")
            ax.grid(alpha=0.3, which="both")
            ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(a.figure, dpi=110)


if __name__ == "__main__":
    main()
