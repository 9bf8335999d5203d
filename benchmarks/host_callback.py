"""What a host (NumPy) black box costs behind ``jax.pure_callback``.

A jitted, vmapped step of a trivial function (x + 0.01 u, nx 4) through
``from_numpy`` per sample and vectorised, against the same step in JAX and the NumPy loop
alone; best of 20 calls per batch size.

    python benchmarks/host_callback.py
"""

from __future__ import annotations

import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def best(f, *args, n: int = 20) -> float:
    import jax

    jax.block_until_ready(f(*args))
    times = []
    for _ in range(n):
        t = time.perf_counter()
        jax.block_until_ready(f(*args))
        times.append(time.perf_counter() - t)
    return min(times)


def main() -> None:
    import mjx_surrogate as ms

    ms.configure_runtime(x64=True)
    import jax
    import jax.numpy as jnp
    import numpy as np

    from mjx_surrogate.systems.function import from_jax, from_numpy

    def one(x, u):
        return x + 0.01 * u[0]

    systems = {
        "host, per sample": from_numpy(one, 4, 1, 0.01),
        "host, vectorised": from_numpy(lambda X, U: X + 0.01 * U[:, :1], 4, 1, 0.01, vectorized=True),
        "JAX": from_jax(lambda x, u: x + 0.01 * u[0], 4, 1, 0.01),
    }
    print("| batch | " + " | ".join(systems) + " | the NumPy loop alone |")
    print("|---|" + "---|" * (len(systems) + 1))
    for B in (1, 100, 10_000):
        X, U = jnp.ones((B, 4)), jnp.ones((B, 1))
        row = [best(jax.jit(jax.vmap(s.step)), X, U) for s in systems.values()]
        xn, un = np.ones((B, 4)), np.ones((B, 1))
        row.append(best(lambda: [one(a, b) for a, b in zip(xn, un)]))
        print(f"| {B} | " + " | ".join(f"{1e6 * t:.0f} us" for t in row) + " |")


if __name__ == "__main__":
    main()
