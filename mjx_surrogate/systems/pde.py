"""Discretisation shared by the PDE black boxes (:mod:`.burgers`, :mod:`.allen_cahn`).

A field w(xi, t) on the periodic unit interval (or square) is held at the cell centres
xi_i = (i + 1/2) h, h = 1/n; the state is the field [n] (or [n * n], row-major). One
control step of length dt is ``substeps`` steps of the semi-implicit (IMEX) Euler scheme

    (I - tau c L_h) w_{k+1} = w_k + tau (N(w_k) + b u),    tau = dt / substeps,

with L_h the periodic 3-point (5-point in 2-D) Laplacian, the stiff diffusion implicit
and the nonlinear term N explicit. L_h is diagonal in the discrete Fourier basis, with
eigenvalues -(2/h)^2 sin^2(pi k / n) (summed over both axes in 2-D), so the implicit solve
is one real FFT, a division and its inverse: O(n log n) per step, exact for the discrete
operator. Actuators are periodic Gaussian bumps b_j(xi) = exp(-d(xi, c_j)^2 / (2 s^2)),
the controls u [nu] their amplitudes.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from mjx_surrogate.systems.function import FunctionSystem, from_jax


def cell_centres(n: int) -> np.ndarray:
    """xi [n]: the cell centres of the periodic unit interval."""
    return (np.arange(n) + 0.5) / n


def bumps_1d(n: int, nu: int, width: float) -> np.ndarray:
    """[n, nu]: nu Gaussian bumps of std ``width`` centred at (j + 1/2) / nu, periodic."""
    xi = cell_centres(n)
    c = (np.arange(nu) + 0.5) / nu
    d = np.abs(xi[:, None] - c[None, :])
    d = np.minimum(d, 1.0 - d)
    return np.exp(-(d**2) / (2 * width**2))


def bumps_2d(n: int, per_side: int, width: float) -> np.ndarray:
    """[n * n, per_side^2]: Gaussian bumps on a per_side x per_side lattice of centres."""
    b = bumps_1d(n, per_side, width)  # [n, p]
    return np.einsum("ia,jb->ijab", b, b).reshape(n * n, per_side * per_side)


def _symbol_1d(n: int) -> np.ndarray:
    """-eigenvalues of L_h for the real-FFT frequencies k = 0 .. n // 2: (2n)^2 sin^2(pi k/n)."""
    k = np.arange(n // 2 + 1)
    return (2.0 * n * np.sin(np.pi * k / n)) ** 2


def implicit_diffusion(n: int, coef: float, tau: float, dims: int = 1):
    """w [n] (or [n * n]) -> (I - tau coef L_h)^-1 w, by real FFT."""
    if dims == 1:
        inv = 1.0 / (1.0 + tau * coef * _symbol_1d(n))

        def solve(w):
            return jnp.fft.irfft(jnp.fft.rfft(w) * inv.astype(w.dtype), n=n)

        return solve
    k = np.fft.fftfreq(n) * n  # full frequencies on the first axis
    s0 = (2.0 * n * np.sin(np.pi * k / n)) ** 2
    inv2 = 1.0 / (1.0 + tau * coef * (s0[:, None] + _symbol_1d(n)[None, :]))

    def solve2(w):
        f = jnp.fft.rfft2(w.reshape(n, n)) * inv2.astype(w.dtype)
        return jnp.fft.irfft2(f, s=(n, n)).reshape(n * n)

    return solve2


def imex_step(explicit, solve, b: np.ndarray, dt: float, substeps: int):
    """step(w [nx], u [nu]) of the module docstring's scheme; explicit(w) = N(w)."""
    tau = dt / substeps

    def step(w, u):
        force = tau * (jnp.asarray(b, w.dtype) @ u)

        def one(_, w):
            return solve(w + tau * explicit(w) + force)

        return jax.lax.fori_loop(0, substeps, one, w)

    return step


def laplacian_matrix(n: int) -> np.ndarray:
    """L_h [n, n], the periodic 3-point Laplacian (for checks against dense algebra)."""
    L = -2.0 * np.eye(n) + np.eye(n, k=1) + np.eye(n, k=-1)
    L[0, -1] = L[-1, 0] = 1.0
    return L * n**2


def field_system(step, b: np.ndarray, dt: float, name: str, u_max: float) -> FunctionSystem:
    """The black box of a field step with actuator shapes b [nx, nu]: states w0.., controls
    u0.., |u_j| <= u_max."""
    nx, nu = b.shape
    return from_jax(
        step,
        nx,
        nu,
        dt,
        name=name,
        state_labels=tuple(f"w{i}" for i in range(nx)),
        control_labels=tuple(f"u{j}" for j in range(nu)),
        u_min=np.full(nu, -u_max),
        u_max=np.full(nu, u_max),
    )


def field_task(x0: np.ndarray, goal: np.ndarray, cell: float, nu: int, T: int) -> dict:
    """Task fields with the weights as integrals over the domain (``cell``: a cell's length
    or area): running cell |w - w*|^2, terminal 10 cell |w - w*|^2, 1e-3 |u|^2 per step. The
    state weights are their diagonals [nx]: no nx x nx array on a grid of many cells."""
    nx = x0.shape[0]
    return dict(
        x0=x0,
        x_goal=goal,
        Q=np.full(nx, cell),
        Q_f=np.full(nx, 10.0 * cell),
        R=1e-3 * np.eye(nu),
        T=T,
        u_ref=np.zeros(nu),
    )
