"""What a registered system module provides (see :mod:`mjx_surrogate.systems.registry`)."""

from __future__ import annotations

from typing import Callable, NamedTuple


class SystemDefaults(NamedTuple):
    """Per-system defaults. ``backend`` is the faster one on a 2-core CPU, as measured
    by ``benchmarks/rollout.py`` (see docs/performance.md)."""

    xml: Callable[[], str]
    substeps: int
    backend: str
