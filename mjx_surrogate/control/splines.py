"""Control splines as constant matrices: a plan held at k knots, read at any times.

A spline through knot values y [k, nu] at knot times tau [k] is linear in y, so reading it
at query times t [q] is one matrix, y(t) = basis(kind, tau, t) @ y with basis [q, k]:

- ``zero``: the last knot at or before t (zero-order hold; the first knot before tau_0);
- ``linear``: straight between knots, the end segments extended beyond them;
- ``cubic``: scipy's not-a-knot cubic spline (``CubicSpline``'s default), its end
  polynomials extended beyond the knots; two knots give the straight line, three the
  parabola.

These are the splines of hydrax's sampling planners (zero-order hold, interpax's linear and
``cubic2`` interpolation, extrapolating), computed once per planner as NumPy constants.
One knot is a constant plan for every kind.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

SplineKind = Literal["zero", "linear", "cubic"]
SPLINES = ("zero", "linear", "cubic")


def basis(kind: SplineKind, tau: np.ndarray, t: np.ndarray) -> np.ndarray:
    """B [q, k]: the ``kind`` spline through values at the increasing knot times tau [k],
    read at times t [q] (module docstring)."""
    tau, t = np.asarray(tau, float), np.asarray(t, float)
    k = len(tau)
    if kind not in SPLINES:
        raise ValueError(f"spline kind: one of {', '.join(SPLINES)}, got {kind!r}")
    if k == 1:
        return np.ones((len(t), 1))
    eye = np.eye(k)
    if kind == "zero":
        return eye[np.clip(np.searchsorted(tau, t, side="right") - 1, 0, k - 1)]
    if kind == "linear":
        seg = np.clip(np.searchsorted(tau, t, side="right") - 1, 0, k - 2)
        w = (t - tau[seg]) / (tau[seg + 1] - tau[seg])
        return (1 - w)[:, None] * eye[seg] + w[:, None] * eye[seg + 1]
    from scipy.interpolate import CubicSpline  # a slow import, deferred to the first cubic plan

    return CubicSpline(tau, eye, axis=0, extrapolate=True)(t)


def knot_times(horizon: int, knots: int) -> np.ndarray:
    """tau [knots] in control steps: ``knots`` spread evenly from the plan's start to the
    horizon's end (step H, one past its last control, as hydrax spreads them over the
    horizon in seconds); knots 0: one knot at every control step 0 .. H-1."""
    if knots == 0:
        return np.arange(horizon, dtype=float)
    return np.linspace(0.0, float(horizon), knots)
