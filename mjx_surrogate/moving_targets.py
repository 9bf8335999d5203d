"""Moving targets for point goals (:class:`mjx_surrogate.tasks.Task`'s ``motion``).

Goal k's target after s seconds, from its start p_k*:

    p_k*(s) = p_k* + v_k s + r_k ((cos phi - 1) e1 + sin phi e2),   phi = 2 pi s / P_k,

a constant velocity v_k [m/s] plus a circle of radius r_k [m] and period P_k [s] through
the start, in the plane of the world axes (e1, e2) ("xy", "xz" or "yz"), turning from e1
towards e2. The motion is a function of the control step n (s = n dt), so that a receding
horizon started at step n sees the targets where they will be.
"""

from __future__ import annotations

from typing import Callable, Sequence

import jax
import jax.numpy as jnp
import numpy as np

PLANES = {"xy": (0, 1), "xz": (0, 2), "yz": (1, 2)}


def target_motion(
    velocity: Sequence[Sequence[float]],
    radius: Sequence[float],
    period: Sequence[float],
    plane: Sequence[str],
    dt: float,
) -> Callable[[jax.Array], jax.Array] | None:
    """n (int32 scalar) -> displacement [k, 3] of the k targets after n control steps of dt
    seconds; velocity [k, 3], radius, period [k] (period ignored where radius is 0), plane
    [k] keys of :data:`PLANES`. None when no target moves."""
    v = np.asarray(velocity, float).reshape(-1, 3)
    r, P = np.asarray(radius, float), np.asarray(period, float)
    if not np.any(v) and not np.any(r):
        return None
    e1, e2 = np.zeros((len(r), 3)), np.zeros((len(r), 3))
    for k, name in enumerate(plane):
        e1[k, PLANES[name][0]], e2[k, PLANES[name][1]] = 1.0, 1.0
    omega = np.where(r > 0, 2 * np.pi / np.where(r > 0, P, 1.0), 0.0)  # [k] rad/s

    def motion(n: jax.Array) -> jax.Array:
        s = n * dt
        phi = (omega * s)[:, None]
        circle = r[:, None] * ((jnp.cos(phi) - 1.0) * e1 + jnp.sin(phi) * e2)
        return v * s + circle

    return motion
