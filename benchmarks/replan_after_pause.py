"""A D2C-MPC replan's wall time after a pause of the calling thread: back to back, after
sleeping, after spinning (a busy Python loop), in the main thread or a thread of its own.
The real-time loop's planner waits for each new measurement (``mjx_surrogate.control.realtime``),
so its replans follow pauses of up to a control period.

    python benchmarks/replan_after_pause.py [--preset hydrax_pendulum_mpc] [--gaps 0 2 5 18]
        [--replans 150]

Every replan starts from the preset's x0 and u_ref plan with its own key; compile apart.
"""

from __future__ import annotations

import argparse
import os
import sys
import threading
import time

_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, _ROOT)


def replanner(preset: str):
    """``one(i)``: the preset's D2C-MPC replan number i, compiled, to the host."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    from experiments.run import load_config
    from mjx_surrogate.control import mpc
    from mjx_surrogate.control.episode import first_plan
    from mjx_surrogate.runs.resolution import mpc_params, resolve

    cfg, system, task = resolve(load_config(preset))
    params, sysid = mpc_params(cfg)
    H = cfg.mpc.horizon
    U0 = jnp.broadcast_to(task.u_ref, (H,) + task.u_ref.shape)
    replan = jax.jit(mpc.d2c_replan(system, task.replace(T=H, deadline=None), params, sysid))
    x0 = np.asarray(task.x0)
    plan0 = jax.tree.map(np.asarray, first_plan(U0, task.x0))
    keys = list(jax.random.split(jax.random.key(cfg.experiment.seed), 64))  # split before timing

    def one(i: int):
        new, _ = replan(x0, plan0, keys[i % len(keys)], np.int32(i))
        return jax.tree.map(np.asarray, jax.block_until_ready(new))

    one(0)
    return one


def timed(one, gap_s: float, busy: bool, n: int) -> float:
    """Median ms of n replans, each after a pause of gap_s (slept or spun)."""
    import numpy as np

    out = []
    for i in range(n):
        t = time.perf_counter()
        one(i)
        out.append(time.perf_counter() - t)
        if busy:
            end = time.perf_counter() + gap_s
            while time.perf_counter() < end:
                pass
        elif gap_s:
            time.sleep(gap_s)
    return 1e3 * float(np.median(out))


def in_thread(fn) -> float:
    res: list = []
    worker = threading.Thread(target=lambda: res.append(fn()))
    worker.start()
    worker.join()
    return res[0]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--preset", default="hydrax_pendulum_mpc")
    ap.add_argument("--gaps", type=float, nargs="*", default=[0.0, 0.5, 2.0, 5.0, 18.0, 50.0], help="ms")
    ap.add_argument("--replans", type=int, default=150)
    args = ap.parse_args()
    if any(g < 0 for g in args.gaps) or args.replans < 1:
        ap.error("--gaps: pauses >= 0 ms; --replans: >= 1")
    from mjx_surrogate.errors import ConfigError
    from mjx_surrogate.runtime import configure_runtime

    configure_runtime()
    try:
        one = replanner(args.preset)
    except ConfigError as e:
        ap.error(f"--preset: {e}")
    print("| pause, ms | slept, main thread | spun, main thread | slept, planner thread |")
    print("|---|---|---|---|")
    for gap in args.gaps:
        g = gap / 1e3
        row = [
            timed(one, g, False, args.replans),
            timed(one, g, True, args.replans),
            in_thread(lambda: timed(one, g, False, args.replans)),
        ]
        print(f"| {gap:g} | " + " | ".join(f"{ms:.2f}" for ms in row) + " |", flush=True)


if __name__ == "__main__":
    main()
