"""What the outputs the solver never reads (sensors, energy) cost the native simulator.

The identification's one-step batches (``NativeSimulator.step``, B rows of perturbed states
and random in-range controls, one control step of 2 substeps) on third-party models as
downloaded, with the simulator as built (sensors and energy off: ``outputs_can_act``) and
with its model copy's flags put back to the model's own; same run, alternated, best of N.
The states are checked equal bit for bit.

    python benchmarks/native_outputs.py [--rows 400] [--repeats 7]
"""

from __future__ import annotations

import argparse
import os
import sys
import time

_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, _ROOT)
sys.path.insert(0, os.path.join(_ROOT, "tests"))

MODELS = [
    ("dm_control", "quadruped"),
    ("dm_control", "humanoid"),
    ("dm_control", "humanoid_CMU"),
    ("dm_control", "dog"),
    ("dm_control", "cheetah"),
    ("gymnasium", "ant"),
]


def _best(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--rows", type=int, default=400, help="rows of each one-step batch")
    ap.add_argument("--repeats", type=int, default=7, help="timed calls of each variant (best kept)")
    a = ap.parse_args()
    import mujoco
    import numpy as np
    from thirdparty import model_path

    from mjx_surrogate.systems.backend_native import NativeSimulator

    print("| model | sensors (values) | batch ms, as built | with sensors and energy | ratio |")
    print("|---|---|---|---|---|")
    for package, name in MODELS:
        path = model_path(package, name + ".xml")
        if path is None:
            print(f"| {package}/{name} | wheel not reachable | | | |")
            continue
        m = mujoco.MjModel.from_xml_path(path)
        rng = np.random.default_rng(0)
        built = NativeSimulator(m, substeps=2, nthread=1)
        full = NativeSimulator(m, substeps=2, nthread=1)
        full.model.opt.disableflags, full.model.opt.enableflags = m.opt.disableflags, m.opt.enableflags
        full.model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_AUTORESET
        x = np.tile(built.template[1 : 1 + built.nx], (a.rows, 1))
        x[:, m.nq : m.nq + m.nv] += 0.1 * rng.standard_normal((a.rows, m.nv))
        lo, hi = m.actuator_ctrlrange[:, 0], m.actuator_ctrlrange[:, 1]
        r = rng.uniform(0, 1, (a.rows, m.nu))
        u = np.where(m.actuator_ctrllimited.astype(bool), lo + (hi - lo) * r, 2 * r - 1)
        assert np.array_equal(built.step(x, u), full.step(x, u), equal_nan=True), name
        t_built = t_full = np.inf
        for _ in range(2):  # alternated: drift of the machine falls on both
            t_built = min(t_built, _best(lambda: built.step(x, u), a.repeats))
            t_full = min(t_full, _best(lambda: full.step(x, u), a.repeats))
        print(
            f"| {package}/{name} | {m.nsensor} ({m.nsensordata}) | {1e3 * t_built:.1f} | "
            f"{1e3 * t_full:.1f} | {t_full / t_built:.2f} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
