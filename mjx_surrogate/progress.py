"""Progress meters fed from inside jitted loops through ``jax.debug.callback``."""

from __future__ import annotations

import contextlib

from tqdm.auto import tqdm

_BAR: list = []


@contextlib.contextmanager
def progress_bar(desc: str, total: int, enabled: bool = True):
    """Open a bar that :func:`report` (called from a jitted solver) advances."""
    bar = tqdm(total=total, desc=desc, disable=not enabled, leave=True, dynamic_ncols=True)
    _BAR.append(bar)
    try:
        yield bar
    finally:
        _BAR.pop()
        bar.close()


def report(iteration, cost, mu) -> None:
    """Host side of the solver's per-iteration callback."""
    if _BAR:
        bar = _BAR[-1]
        bar.n = int(iteration)
        bar.set_postfix(J=f"{float(cost):.5g}", mu=f"{float(mu):.1e}", refresh=False)
        bar.refresh()
