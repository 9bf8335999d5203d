"""Compile time apart from run time, via JAX's ahead-of-time API."""

from __future__ import annotations

import time
from typing import Any, Callable, NamedTuple

import jax


class Timed(NamedTuple):
    out: Any
    compile_s: float  # tracing, lowering and XLA compilation
    run_s: float  # the compiled call, to completion (median over the repeats)


def compile_then_run(
    fn: Callable,
    static_args: tuple,
    dynamic_args: tuple,
    repeats: int = 1,
    static_kwargs: dict | None = None,
    dynamic_kwargs: dict | None = None,
    compiler_options: dict | None = None,
) -> Timed:
    """``fn`` is a ``jax.jit`` whose leading positional parameters are static (more static
    parameters may come by keyword); it is compiled with ``compiler_options`` (e.g.
    ``System.compiler_options``), the compiled call runs ``repeats`` times on the same
    inputs and the median time is reported."""
    t0 = time.perf_counter()
    dyn_kw = dynamic_kwargs or {}
    lowered = fn.lower(*static_args, *dynamic_args, **(static_kwargs or {}), **dyn_kw)
    compiled = lowered.compile(compiler_options)
    t1 = time.perf_counter()
    times = []
    for _ in range(max(1, repeats)):
        t = time.perf_counter()
        out = jax.block_until_ready(compiled(*dynamic_args, **dyn_kw))
        times.append(time.perf_counter() - t)
    return Timed(out, t1 - t0, sorted(times)[len(times) // 2])
