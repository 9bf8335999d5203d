"""Where a SINDy fit's least-squares solve runs when the data's rows are spread over devices.

The prediction study samples its trajectories over the system's mesh, so with
``--cpu-devices 2`` (the reproduction's setting) the transitions' rows lie on two CPU
devices. A SINDy fit on them is one least-squares SVD; XLA partitions it across the
devices, or :func:`mjx_surrogate.sharding.on_one_device` gathers the rows first (what the
``sindy`` and ``pod_sindy`` kinds do). This times both on a random design of a study's size,
float64, in one run: the best of 3 solves each, compile apart, and the largest difference
between the two solutions.

    python benchmarks/sindy_placement.py [--rows 9000] [--features 2701]

(9000 x 2701: the Burgers study's quadratic library on 72 inputs; 108000 x 561: the fish's.)
"""

from __future__ import annotations

import argparse
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--rows", type=int, default=9000)
    ap.add_argument("--features", type=int, default=2701)
    ap.add_argument("--targets", type=int, default=64)
    a = ap.parse_args()
    for field in ("rows", "features", "targets"):
        if getattr(a, field) < 1:
            ap.error(f"--{field}: a size >= 1, got {getattr(a, field)}")
    import jax

    jax.config.update("jax_num_cpu_devices", 2)
    import mjx_surrogate as ms

    ms.configure_runtime(x64=True)
    import numpy as np
    from jax.sharding import NamedSharding, PartitionSpec

    from mjx_surrogate import sharding
    from mjx_surrogate.surrogates import sindy

    mesh = sharding.device_mesh(2, jax.devices())
    kx, ky = jax.random.split(jax.random.key(0))
    theta = jax.random.normal(kx, (a.rows, a.features))
    y = jax.random.normal(ky, (a.rows, a.targets))
    rows = NamedSharding(mesh, PartitionSpec(mesh.axis_names[0]))
    spread = (jax.device_put(theta, rows), jax.device_put(y, rows))

    def timed(args) -> tuple[float, float, jax.Array]:
        t = time.perf_counter()
        c = jax.block_until_ready(sindy.lstsq(*args))  # the first call compiles
        first = time.perf_counter() - t
        runs = []
        for _ in range(3):
            t = time.perf_counter()
            jax.block_until_ready(sindy.lstsq(*args))
            runs.append(time.perf_counter() - t)
        return first - min(runs), min(runs), c

    compile_s, spread_s, c_spread = timed(spread)
    compile_1, one_s, c_one = timed(sharding.on_one_device(*spread))
    c_spread, c_one = np.asarray(c_spread), np.asarray(c_one)  # on different devices
    diff = float(np.max(np.abs(c_spread - c_one)) / np.max(np.abs(c_one)))
    print(f"design {a.rows} x {a.features}, {a.targets} targets, float64, 2 CPU devices")
    print("| rows | solve s | compile s (about) |")
    print("|---|---|---|")
    print(f"| spread over 2 devices | {spread_s:.2f} | {compile_s:.1f} |")
    print(f"| gathered on one (`on_one_device`) | {one_s:.2f} | {compile_1:.1f} |")
    print(f"ratio {spread_s / one_s:.2f}x; largest difference of the solutions {diff:.1e} (relative)")
    np.testing.assert_allclose(c_spread, c_one, rtol=1e-6, atol=1e-9)


if __name__ == "__main__":
    main()
