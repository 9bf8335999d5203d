"""XLA CPU flags, applied before JAX initialises its backend.

XLA's CPU fusion emitters made MJX rollouts up to ~50x slower and compiles minutes long
on many-body models (measured in benchmarks/rollout.py, docs/performance.md), so they
are switched off unless the user set ``XLA_FLAGS`` themselves or sets
``MJX_SURROGATE_KEEP_XLA_FLAGS=1``.
"""

import os

_FLAG = "--xla_cpu_use_fusion_emitters=false"

if not os.environ.get("MJX_SURROGATE_KEEP_XLA_FLAGS"):
    flags = os.environ.get("XLA_FLAGS", "")
    if "xla_cpu_use_fusion_emitters" not in flags:
        os.environ["XLA_FLAGS"] = (flags + " " + _FLAG).strip()
