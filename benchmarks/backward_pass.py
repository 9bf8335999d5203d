"""The iLQR backward pass now and before the regularisation share ``reg`` was added.

Same run, same inputs, compile apart: ``python benchmarks/backward_pass.py BEFORE.py``
where BEFORE.py is an earlier ``mjx_surrogate/control/riccati.py`` (``mjx_surrogate/control/ilqr.py`` before
the backward pass had its own module; e.g. ``git show REV:mjx_surrogate/control/riccati.py``).
Shapes: cartpole (T 30, nx 4, nu 1) and fish (T 600, nx 27, nu 5), unbounded and boxed.
"""

from __future__ import annotations

import importlib.util
import sys
import time


def _timed(fs, args, reps=100, rounds=7):
    """Best-of-``rounds`` mean seconds per call of each of ``fs``, rounds interleaved."""
    import jax

    for f in fs:
        jax.block_until_ready(f(*args))  # compile
    best = [float("inf")] * len(fs)
    for _ in range(rounds):
        for i, f in enumerate(fs):
            t0 = time.perf_counter()
            for _ in range(reps):
                jax.block_until_ready(f(*args))
            best[i] = min(best[i], (time.perf_counter() - t0) / reps)
    return best


def main() -> None:
    from mjx_surrogate.runtime import configure_runtime

    configure_runtime(x64=True)
    import jax
    import jax.numpy as jnp

    from mjx_surrogate.control.riccati import backward_pass

    spec = importlib.util.spec_from_file_location("ilqr_before", sys.argv[1])
    before = importlib.util.module_from_spec(spec)
    sys.modules["ilqr_before"] = before  # dataclasses look their module up
    spec.loader.exec_module(before)
    print("| shape | limits | before ms | now ms | now / before |\n|---|---|---|---|---|")
    for name, T, nx, nu in (("cartpole", 30, 4, 1), ("fish", 600, 27, 5)):
        k = jax.random.split(jax.random.key(0), 4)
        A = jnp.eye(nx) + 0.01 * jax.random.normal(k[0], (T, nx, nx))
        B = 0.1 * jax.random.normal(k[1], (T, nx, nu))
        lx, lu = jnp.zeros((T, nx)), jnp.zeros((T, nu))
        lxx, luu, lux = (
            jnp.broadcast_to(jnp.eye(nx), (T, nx, nx)),
            jnp.broadcast_to(0.01 * jnp.eye(nu), (T, nu, nu)),
            jnp.zeros((T, nu, nx)),
        )
        args = (A, B, lx, lu, lxx, luu, lux, jnp.ones(nx), 10 * jnp.eye(nx), jnp.zeros((T, nu)))
        for limits in ("none", "box"):
            lo, hi = (
                (jnp.full(nu, -jnp.inf), jnp.full(nu, jnp.inf))
                if limits == "none"
                else (-jnp.ones(nu), jnp.ones(nu))
            )
            f_now = jax.jit(lambda *a: backward_pass(*a, lo, hi, 1e-6))
            f_before = jax.jit(lambda *a: before.backward_pass(*a, lo, hi, 1e-6))
            t_b, t_n = _timed((f_before, f_now), args)
            print(f"| {name} | {limits} | {1e3 * t_b:.3f} | {1e3 * t_n:.3f} | {t_n / t_b:.2f} |", flush=True)


if __name__ == "__main__":
    main()
