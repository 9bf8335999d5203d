"""The Allen-Cahn phase-field equation with distributed actuation, 1-D and 2-D.

    dw/dt = eps^2 lap(w) + w - w^3 + sum_j b_j u_j,    periodic unit interval / square

the phase-field model of microstructure evolution on which the authors tested reduced-order
iLQR (Sharma and Chakravorty, ACC 2023, arXiv 2501.06635) and D2C (Sharma et al., ASME
JDSMC 146(6) 061109, 2024). w = -1 and w = +1 are the two phases (stable), w = 0 is
unstable: driving the field from one phase to a pattern of both is a nonlinear problem.
The parameters are this project's choice: eps = 0.05 (interfaces about 0.07 wide), control
period dt = 0.02 s, two IMEX substeps (:mod:`.pde`, the reaction w - w^3 explicit); 1-D:
eight actuators (bumps of std 1/16), 2-D: a 3 x 3 lattice of bumps of std 1/8.

The tasks: from the uniform phase w = -1, grow the +1 phase in the middle of the domain
(1-D: |xi - 1/2| < 1/4; 2-D: a disc of radius 1/4), the target profile tanh of the
signed distance to the interface over sqrt(2) eps (the equation's own interface shape),
in 1 s (50 steps); h-weighted weights as for Burgers: running h^d |w - w*|^2, terminal
10 h^d |w - w*|^2, controls 1e-3 |u|^2 per step, |u_j| <= 10.
"""

from __future__ import annotations

import numpy as np

from mjx_surrogate.systems.function import FunctionSystem
from mjx_surrogate.systems.pde import (
    bumps_1d,
    bumps_2d,
    cell_centres,
    field_system,
    field_task,
    imex_step,
    implicit_diffusion,
)
from mjx_surrogate.tasks import TaskPreset

EPS = 0.05
DT = 0.02
SUBSTEPS = 2
U_MAX = 10.0
DEFAULT_GRID = 64
DEFAULT_GRID_2D = 16


def reaction(w):
    return w - w * w * w


def make_system(n: int = DEFAULT_GRID, dims: int = 1) -> FunctionSystem:
    """Allen-Cahn on n cells (dims = 1) or n x n cells (dims = 2)."""
    if n < 8:
        raise ValueError(f"allen_cahn needs at least 8 cells per side, got {n}")
    b = bumps_1d(n, 8, 1.0 / 16.0) if dims == 1 else bumps_2d(n, 3, 1.0 / 8.0)
    step = imex_step(reaction, implicit_diffusion(n, EPS**2, DT / SUBSTEPS, dims), b, DT, SUBSTEPS)
    return field_system(step, b, DT, f"allen_cahn{n}" if dims == 1 else f"allen_cahn2d{n}", U_MAX)


def target_profile(n: int, dims: int = 1) -> np.ndarray:
    """w* [n^dims]: +1 inside the middle region, -1 outside, tanh(d / (sqrt(2) eps))."""
    xi = cell_centres(n)
    if dims == 1:
        d = 0.25 - np.abs(xi - 0.5)
    else:
        d = (0.25 - np.hypot(xi[:, None] - 0.5, xi[None, :] - 0.5)).reshape(-1)
    return np.tanh(d / (np.sqrt(2.0) * EPS))


def grow_fields(nx: int, nu: int, T: int = 50) -> dict:
    """The growth task on a system with nx cells (2-D when nu is 9: n = sqrt(nx))."""
    dims = 2 if nu == 9 else 1
    n = int(round(nx ** (1.0 / dims)))
    return field_task(-np.ones(nx), target_profile(n, dims), 1.0 / nx, nu, T)  # 1/nx: a cell's size


TASKS = {
    "allen_cahn_grow": TaskPreset(
        "allen_cahn*",
        lambda nq, nv, nu: grow_fields(nq, nu),
        "Allen-Cahn (1-D or 2-D): grow the +1 phase in the middle from w = -1 in 1 s (50 steps)",
    ),
}
