"""``jax.jit`` for functions of a system: each program compiles with that system's XLA options.

A solve's first argument is its (static) system; :attr:`System.compiler_options` says how
its programs are compiled (a lower XLA backend optimisation level on the native backend,
whose programs compile faster so). The command line's
chunked driver passes those options when it compiles; :func:`system_jit` gives a public
API call the same programs, so a notebook's solve and the command line's compile alike.
"""

from __future__ import annotations

import functools
from typing import Callable

import jax


class SystemJit:
    """``fn(system, ...)`` jitted once per distinct ``system.compiler_options`` (a system
    without that attribute gets XLA's defaults); called and lowered as a ``jax.jit`` is."""

    def __init__(self, fn: Callable, static_argnames: tuple[str, ...]):
        self._fn, self._static = fn, static_argnames
        self._jits: dict[tuple, Callable] = {}
        functools.update_wrapper(self, fn)

    def _jit_for(self, system) -> Callable:
        options = getattr(system, "compiler_options", None) or {}  # a user object may not say
        key = tuple(sorted(options.items()))
        if key not in self._jits:
            jit = jax.jit(self._fn, static_argnames=self._static, compiler_options=options or None)
            self._jits[key] = jit
        return self._jits[key]

    def __call__(self, system, *args, **kwargs):
        return self._jit_for(system)(system, *args, **kwargs)

    def lower(self, system, *args, **kwargs):
        return self._jit_for(system).lower(system, *args, **kwargs)

    def _cache_size(self) -> int:
        """Programs traced so far, over every options set (the no-recompilation tests)."""
        return sum(j._cache_size() for j in self._jits.values())


def system_jit(static_argnames: tuple[str, ...]) -> Callable[[Callable], SystemJit]:
    """Decorator: :class:`SystemJit` of the function; ``static_argnames`` must name the system."""
    assert "system" in static_argnames
    return lambda fn: SystemJit(fn, static_argnames)
