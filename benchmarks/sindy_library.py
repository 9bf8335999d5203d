"""Compile and run time of a SINDy library's features and of the Jacobians iLQR takes of a
SINDy step, the library's vectorised evaluation against a column-by-column one (one
gather and product per column, the form the library had before).

    python benchmarks/sindy_library.py [--T 600] [--rows 24000] [--per-column-max 1000]

Float64, the persistent compilation cache off, synthetic states (the timings depend on
the shapes only). Per case: P, then for the Jacobians of x' = Theta([x, u]) C at T
points (``vmap(jacfwd)``) and for the design matrix Theta on ``--rows`` rows: lower +
compile seconds and the median of 7 runs.
The column-by-column form is skipped above ``--per-column-max`` columns (its compile
grows with P: minutes for a cubic library of 32 variables).
"""

from __future__ import annotations

import os as _os
import sys as _sys

_sys.path.insert(0, _os.path.dirname(_os.path.dirname(_os.path.abspath(__file__))))

import argparse
import time

import numpy as np

CASES = (  # name, nx, nu, library name, trig coordinates
    ("cartpole quartic_trig", 4, 1, "quartic_trig", (1,)),
    ("cartpole poly3_trig_prod", 4, 1, "poly3_trig_prod", (1,)),
    ("fish poly2", 27, 5, "poly2", ()),
    ("fish poly2_trig", 27, 5, "poly2_trig", tuple(range(7, 14))),
    ("fish poly3", 27, 5, "poly3", ()),
)


def per_column_features(spec, z):
    """Theta(z) one column at a time: the reference form."""
    import jax.numpy as jnp

    from mjx_surrogate.surrogates import library

    cols = [
        jnp.prod(z[..., list(t)], axis=-1) if t else jnp.ones(z.shape[:-1], z.dtype)
        for t in library._monomials(spec, z.shape[-1])
    ]
    trig = [getattr(jnp, fn)(h * z[..., j]) for fn, h, j in library._trig_terms(spec)]
    prods = [m * t for m in cols[int(spec.bias) :] for t in trig] if spec.products else []
    return jnp.stack(cols + trig + prods, axis=-1)


def _timed(f, *args) -> tuple[float, float]:
    import jax

    t0 = time.perf_counter()
    compiled = jax.jit(f).lower(*args).compile()
    compile_s = time.perf_counter() - t0
    jax.block_until_ready(compiled(*args))
    runs = []
    for _ in range(7):
        t0 = time.perf_counter()
        jax.block_until_ready(compiled(*args))
        runs.append(time.perf_counter() - t0)
    return compile_s, float(np.median(runs))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--T", type=int, default=600, help="points at which the Jacobians are taken")
    ap.add_argument("--rows", type=int, default=24000, help="rows of the design matrix")
    ap.add_argument("--per-column-max", type=int, default=1000, help="largest P timed column by column")
    a = ap.parse_args()
    from mjx_surrogate.runtime import configure_runtime

    configure_runtime(x64=True, compile_cache=False)  # cold compiles every run
    import jax
    import jax.numpy as jnp

    from mjx_surrogate.surrogates import library

    rng = np.random.default_rng(0)
    print("| case | P | form | Jacobians compile s | Jacobians run ms | design compile s | design run ms |")
    print("|---|---|---|---|---|---|---|")
    for name, nx, nu, lib, trig in CASES:
        spec = library.parse(lib, trig)
        P = library.size(spec, nx + nu)
        C = jnp.asarray(1e-3 * rng.normal(size=(P, nx)))
        X, U = jnp.asarray(0.1 * rng.normal(size=(a.T, nx))), jnp.asarray(0.1 * rng.normal(size=(a.T, nu)))
        Z = jnp.asarray(0.1 * rng.normal(size=(a.rows, nx + nu)))
        forms = [("vectorised", library.features)]
        if P <= a.per_column_max:
            forms.append(("per column", per_column_features))
        for form, feats in forms:

            def jacobians(X, U, feats=feats):
                step = lambda x, u: feats(spec, jnp.concatenate([x, u])) @ C  # noqa: E731
                return jax.vmap(jax.jacfwd(step, argnums=(0, 1)))(X, U)

            jc, jr = _timed(jacobians, X, U)
            dc, dr = _timed(lambda Z, feats=feats: feats(spec, Z), Z)
            row = f"| {name} | {P} | {form} | {jc:.2f} | {jr * 1e3:.1f} | {dc:.2f} | {dr * 1e3:.1f} |"
            print(row, flush=True)


if __name__ == "__main__":
    main()
