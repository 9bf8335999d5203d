"""The paper's Section "Data Driven Solutions", checked with exact arithmetic.

For a scalar x sampled from p and a basis psi_0 .. psi_N, the data-based normal equations
use G^R_kl = (1/R) sum_i psi_k(x_i) psi_l(x_i), an unbiased estimate of the Gram matrix
G_kl = E[psi_k psi_l] with variance sigma_kl^2 / R, sigma_kl^2 = Var[psi_k psi_l]. Every
such quantity is a polynomial moment, computed here exactly (``fractions.Fraction``):

* N(0, s^2): E[x^(2k)] = (2k-1)!! s^(2k), odd moments 0;
* U(-a, a): E[x^(2k)] = a^(2k) / (2k+1).

Bases: monomials x^n; normalised probabilists' Hermite He_n(x/s)/sqrt(n!) (orthonormal
under N(0, s^2)); normalised Legendre sqrt(2n+1) P_n(x/a) (orthonormal under U(-a, a)).
Condition numbers of G are exact to float64 relative precision for any order: the largest
eigenvalues of G and of its exact rational inverse are both well-conditioned problems.
No JAX here: this is exact reference arithmetic, independent of the engine's numerics.
"""

from __future__ import annotations

import math
from fractions import Fraction
from typing import Literal

import numpy as np

Dist = Literal["gauss", "uniform"]
Basis = Literal["monomial", "hermite", "legendre"]


def double_factorial(n: int) -> int:
    """n!! with (-1)!! = 0!! = 1."""
    return 1 if n <= 0 else math.prod(range(n, 0, -2))


def moment(k: int, dist: Dist, scale: Fraction | int = 1) -> Fraction:
    """E[x^k] under N(0, scale^2) ("gauss") or U(-scale, scale) ("uniform")."""
    if k % 2:
        return Fraction(0)
    s = Fraction(scale) ** k
    return s * double_factorial(k - 1) if dist == "gauss" else s / (k + 1)


def _poly_mul(a: list[Fraction], b: list[Fraction]) -> list[Fraction]:
    out = [Fraction(0)] * (len(a) + len(b) - 1)
    for i, ai in enumerate(a):
        if ai:
            for j, bj in enumerate(b):
                out[i + j] += ai * bj
    return out


def basis_coefficients(basis: Basis, n: int, scale: Fraction | int = 1) -> list[list[Fraction]]:
    """Monomial coefficients (ascending, in x) of the unnormalised psi_0 .. psi_n; the
    normalisation constants (1/sqrt(n!), sqrt(2n+1)) are applied apart, squared, so that
    everything stays rational (:func:`_norm2`)."""
    s = Fraction(scale)
    ys: list[list[Fraction]] = []  # polynomials in y = x / s
    for m in range(n + 1):
        if basis == "monomial" or m < 2:
            y = [Fraction(0)] * m + [Fraction(1)]
        else:
            xp1 = [Fraction(0)] + ys[m - 1]
            p2 = ys[m - 2] + [Fraction(0)] * 2
            if basis == "hermite":  # He_m = y He_{m-1} - (m-1) He_{m-2}
                y = [a - (m - 1) * p2[i] for i, a in enumerate(xp1)]
            else:  # m P_m = (2m-1) y P_{m-1} - (m-1) P_{m-2}
                y = [((2 * m - 1) * a - (m - 1) * p2[i]) / m for i, a in enumerate(xp1)]
        ys.append(y)
    if basis == "monomial":
        return ys
    return [[c / s**j for j, c in enumerate(y)] for y in ys]


def _norm2(basis: Basis, m: int) -> Fraction:
    """Square of the normalisation constant of psi_m."""
    if basis == "hermite":
        return Fraction(1, math.factorial(m))
    if basis == "legendre":
        return Fraction(2 * m + 1)
    return Fraction(1)


def expectation(poly: list[Fraction], dist: Dist, scale=1) -> Fraction:
    return sum((c * moment(j, dist, scale) for j, c in enumerate(poly) if c), Fraction(0))


def gram_exact(basis: Basis, n: int, dist: Dist, scale=1) -> list[list[Fraction]]:
    """G_kl = E[psi_k psi_l], k, l = 0..n, exactly."""
    P = basis_coefficients(basis, n, scale)
    return [
        [expectation(_poly_mul(P[k], P[l]), dist, scale) * _sqrt_norm(basis, k, l) for l in range(n + 1)]
        for k in range(n + 1)
    ]


def _sqrt_norm(basis: Basis, k: int, l: int) -> Fraction:
    # products psi_k psi_l carry c_k c_l; only diagonal and even pairs matter for the
    # orthonormal bases, where c_k c_l is rational when k == l
    if k == l:
        return _norm2(basis, k)
    v = _norm2(basis, k) * _norm2(basis, l)
    r = math.isqrt(v.numerator), math.isqrt(v.denominator)
    if Fraction(r[0] ** 2, r[1] ** 2) == v:
        return Fraction(*r)
    return Fraction(math.sqrt(v))  # off-diagonal products vanish for these bases anyway


def entry_variance(basis: Basis, k: int, l: int, dist: Dist, scale=1) -> Fraction:
    """sigma_kl^2 = Var[psi_k psi_l] = E[(psi_k psi_l)^2] - (E[psi_k psi_l])^2."""
    P = basis_coefficients(basis, max(k, l), scale)
    prod = _poly_mul(P[k], P[l])
    c = _sqrt_norm(basis, k, l)
    return c * c * (expectation(_poly_mul(prod, prod), dist, scale) - expectation(prod, dist, scale) ** 2)


def condition_number(G: list[list[Fraction]]) -> float:
    """cond_2(G) of an SPD rational matrix: lambda_max(G) * lambda_max(G^-1)."""
    inv = _inverse(G)
    lam = np.linalg.eigvalsh(np.array(G, float))[-1]
    lam_inv = np.linalg.eigvalsh(np.array(inv, float))[-1]
    return float(lam * lam_inv)


def _inverse(G: list[list[Fraction]]) -> list[list[Fraction]]:
    n = len(G)
    M = [list(row) + [Fraction(int(i == j)) for j in range(n)] for i, row in enumerate(G)]
    for i in range(n):
        p = next(r for r in range(i, n) if M[r][i] != 0)
        M[i], M[p] = M[p], M[i]
        piv = M[i][i]
        M[i] = [v / piv for v in M[i]]
        for r in range(n):
            if r != i and M[r][i] != 0:
                f = M[r][i]
                M[r] = [a - f * b for a, b in zip(M[r], M[i])]
    return [row[n:] for row in M]


# ---- the paper's formulas (Section "Ill-Conditioning of the Linear Least-Squares Solution")


def paper_monomial_variance(N: int, sigma: float) -> float:
    """[(4N-1)!! - ((2N-1)!!)^2] sigma^(4N): Var[x^(2N)] under N(0, sigma^2)."""
    return (double_factorial(4 * N - 1) - double_factorial(2 * N - 1) ** 2) * sigma ** (4 * N)


def paper_hermite_samples(N: int, sigma: float) -> float:
    """[(4N-1)!! - ((2N-1)!!)^2] / (N!)^2 * sigma^(2N), as printed in the paper."""
    return (
        (double_factorial(4 * N - 1) - double_factorial(2 * N - 1) ** 2)
        / math.factorial(N) ** 2
        * sigma ** (2 * N)
    )


def paper_legendre_samples(N: int, sigma: float) -> float:
    """(2N)!^2 4N^2 / ((N!)^4 (2N+1)^2 (4N+1)) * sigma^(2N), as printed in the paper."""
    return (
        math.factorial(2 * N) ** 2
        * 4
        * N**2
        / (math.factorial(N) ** 4 * (2 * N + 1) ** 2 * (4 * N + 1))
        * sigma ** (2 * N)
    )


def paper_condition(N: int, sigma: float) -> float:
    """The paper's conditioning estimate G_NN / G_00 = E[x^(2N)] = (2N-1)!! sigma^(2N)
    (its text writes (2N)!!; both are printed by the theory experiment)."""
    return double_factorial(2 * N - 1) * sigma ** (2 * N)


def samples_needed(variance: float, mean: float, rel_tol: float = 0.1) -> float:
    """R with std(G^R) = sqrt(variance / R) equal to rel_tol * |mean| (one CLT std)."""
    return variance / (rel_tol * abs(mean)) ** 2


def monte_carlo_gram(
    basis: Basis, n: int, dist: Dist, scale: float, R: int, trials: int, rng: np.random.Generator
) -> np.ndarray:
    """G^R for `trials` independent data sets of R samples: [trials, n+1, n+1] (float64)."""
    x = rng.normal(0.0, scale, (trials, R)) if dist == "gauss" else rng.uniform(-scale, scale, (trials, R))
    P = basis_coefficients(basis, n, Fraction(scale).limit_denominator(10**9))
    c = np.sqrt([float(_norm2(basis, m)) for m in range(n + 1)])
    psi = np.stack(
        [np.polynomial.polynomial.polyval(x, [float(a) for a in P[m]]) * c[m] for m in range(n + 1)], axis=-1
    )  # [trials, R, n+1]
    return np.einsum("tri,trj->tij", psi, psi) / R
