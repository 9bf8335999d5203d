"""The viscous Burgers equation with distributed actuation, a high-dimensional black box.

    dw/dt + w dw/dxi = nu_visc d2w/dxi2 + sum_j b_j(xi) u_j,    xi in [0, 1), periodic

the equation on which the authors tested reduced-order iLQR (Sharma and Chakravorty,
ACC 2023, arXiv 2501.06635) and on which Huang and Kramer (arXiv 2012.02305) compare
reduced models for iLQR. The parameters are this project's choice: nu_visc = 0.01, eight
actuators (Gaussian bumps of std 1/16 at (j + 1/2)/8), control period dt = 0.01 s, two
IMEX substeps (:mod:`.pde`; the convection term w dw/dxi = d(w^2/2)/dxi by central
differences, (w_{i+1}^2 - w_{i-1}^2) / (4h), explicit). With |w| <= 1.4 the scheme is
stable for every grid: tau w^2 <= 2 nu_visc, whatever h.

The task (``burgers_damp``): the travelling wave w(xi, 0) = sin(2 pi xi), which steepens
towards a shock, damped to rest in 0.5 s (50 steps); the weights are integrals over the
domain (h-weighted), so that costs compare across grid sizes: running h |w|^2, terminal
10 h |w|^2, controls 1e-3 |u|^2 per step, |u_j| <= 5.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from mjx_surrogate.systems.function import FunctionSystem
from mjx_surrogate.systems.pde import (
    bumps_1d,
    cell_centres,
    field_system,
    field_task,
    imex_step,
    implicit_diffusion,
)
from mjx_surrogate.tasks import TaskPreset

VISCOSITY = 0.01
N_ACTUATORS = 8
DT = 0.01
SUBSTEPS = 2
DEFAULT_GRID = 64


def convection(n: int):
    """-d(w^2/2)/dxi [n] by central differences on the periodic grid."""

    def minus_flux_derivative(w):
        w2 = w * w
        return -(jnp.roll(w2, -1) - jnp.roll(w2, 1)) * (n / 4.0)

    return minus_flux_derivative


def make_system(
    n: int = DEFAULT_GRID, viscosity: float = VISCOSITY, convective: bool = True
) -> FunctionSystem:
    """Burgers on n cells; ``convective`` False drops w dw/dxi: the heat equation, linear."""
    if n < 8:
        raise ValueError(f"burgers needs at least 8 cells, got {n}")
    b = bumps_1d(n, N_ACTUATORS, 1.0 / 16.0)
    solve = implicit_diffusion(n, viscosity, DT / SUBSTEPS)
    explicit = convection(n) if convective else (lambda w: 0.0 * w)
    step = imex_step(explicit, solve, b, DT, SUBSTEPS)
    return field_system(step, b, DT, f"burgers{n}" if convective else f"heat{n}", 5.0)


def damp_fields(n: int, T: int = 50) -> dict:
    """The ``burgers_damp`` task on n cells (module docstring)."""
    return field_task(np.sin(2 * np.pi * cell_centres(n)), np.zeros(n), 1.0 / n, N_ACTUATORS, T)


TASKS = {
    "burgers_damp": TaskPreset(
        "burgers*",
        lambda nq, nv, nu: damp_fields(nq),
        "Burgers: damp the steepening wave sin(2 pi xi) to rest in 0.5 s (50 steps)",
    ),
}
