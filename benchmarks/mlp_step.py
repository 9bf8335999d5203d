"""One SGD step of the paper's MLP on CPU: the epochs' minibatch order by
``surrogates.mlp.shuffled`` (one single-operand sort) against ``jax.random.permutation``
(its key-value sorts), compile apart.

    python benchmarks/mlp_step.py [--rows 25600] [--epochs 30]

Trains the paper's network (3 -> 32 -> 64 -> 2, batch 256, Adam) on ``--rows`` synthetic
transitions both ways (best of 3 runs each, alternated) and prints microseconds per SGD
step, and the time of one permutation of the rows each way.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=25_600)
    ap.add_argument("--epochs", type=int, default=30)
    a = ap.parse_args()
    if a.rows < 256 or a.epochs < 1:
        ap.error("--rows >= 256 (one batch), --epochs >= 1")

    from mjx_surrogate.runtime import configure_runtime

    configure_runtime(x64=True)
    import jax
    import jax.numpy as jnp

    from mjx_surrogate.surrogates import mlp

    spec = mlp.MLPSpec(widths=(32, 64), epochs=a.epochs, batch_size=256)
    z = jax.random.normal(jax.random.key(0), (a.rows, 3))
    y = jnp.sin(z[:, :2]) + z[:, 2:3]
    zt, yt = z[:1000], y[:1000]
    one_sort = mlp.shuffled
    ways = {"one sort (shuffled)": one_sort, "jax.random.permutation": jax.random.permutation}
    best = dict.fromkeys(ways, float("inf"))
    for i in range(3):
        for name, fn in ways.items():
            mlp.shuffled = fn
            jax.clear_caches()  # mlp.train looks shuffled up when it traces
            jax.block_until_ready(mlp.train(spec, jax.random.key(1), z, y, zt, yt).model.params)  # compile
            t = time.perf_counter()
            jax.block_until_ready(mlp.train(spec, jax.random.key(2 + i), z, y, zt, yt).model.params)
            best[name] = min(best[name], time.perf_counter() - t)
    mlp.shuffled = one_sort
    steps = a.epochs * (a.rows // 256)
    for name, fn in ways.items():
        perm = jax.jit(lambda k, fn=fn: jax.lax.map(lambda kk: fn(kk, a.rows), jax.random.split(k, 30)))
        jax.block_until_ready(perm(jax.random.key(0)))
        t = time.perf_counter()
        jax.block_until_ready(perm(jax.random.key(1)))
        per = (time.perf_counter() - t) / 30
        step = 1e6 * best[name] / steps
        print(f"{name:24s} {step:7.1f} us per SGD step; one permutation {1e3 * per:.2f} ms")


if __name__ == "__main__":
    main()
