"""Feature libraries Theta(z) for linear-in-parameters (SINDy-style) models.

z = [x, u] [nz]. A :class:`LibrarySpec` names the candidate functions:

* polynomials of z up to ``degree`` (with the constant if ``bias``); with ``cross_terms``
  every monomial z_{i1} ... z_{ik}, k <= degree (index tuples in
  ``itertools.combinations_with_replacement`` order), otherwise only pure powers z_i^k;
* sin(h z_j), cos(h z_j) for j in ``trig_coords`` and h = 1 .. ``harmonics``;
* with ``products``, every product of a non-constant monomial and a trig term.

Column order (polynomials, then trig terms by harmonic and coordinate, then products)
follows pysindy's PolynomialLibrary + FourierLibrary (* for products), so coefficients
can be compared with pysindy column by column. The library size P is static.
"""

from __future__ import annotations

import functools
import itertools
from typing import NamedTuple, Tuple

import jax
import jax.numpy as jnp
import numpy as np


class LibrarySpec(NamedTuple):
    degree: int = 3
    cross_terms: bool = True
    bias: bool = True
    trig_coords: Tuple[int, ...] = ()
    harmonics: int = 1
    products: bool = False


def _monomials(spec: LibrarySpec, nz: int) -> list[tuple[int, ...]]:
    terms = [()] if spec.bias else []
    if spec.cross_terms:
        for d in range(1, spec.degree + 1):
            terms += list(itertools.combinations_with_replacement(range(nz), d))
    else:
        terms += [(j,) * d for d in range(1, spec.degree + 1) for j in range(nz)]
    return terms


def _trig_terms(spec: LibrarySpec) -> list[tuple[str, int, int]]:
    return [
        (fn, h, j) for h in range(1, spec.harmonics + 1) for j in spec.trig_coords for fn in ("sin", "cos")
    ]


def size(spec: LibrarySpec, nz: int) -> int:
    """Number of features P."""
    n_mono = len(_monomials(spec, nz))
    n_trig = len(_trig_terms(spec))
    n_prod = (n_mono - int(spec.bias)) * n_trig if spec.products else 0
    return n_mono + n_trig + n_prod


class SpecError(ValueError):
    """A library spec that does not fit; ``part`` names the offending part of the spec."""

    def __init__(self, part: str, message: str):
        super().__init__(f"{part}: {message}")
        self.part, self.message = part, message


def validate(spec: LibrarySpec, nz: int) -> None:
    """Raise SpecError (naming degree, harmonics, trig_coords or library) if the spec does
    not fit z of size nz."""
    if spec.degree < 0:
        raise SpecError("degree", f"must be >= 0, got {spec.degree}")
    if spec.harmonics < 1:
        raise SpecError("harmonics", f"must be >= 1, got {spec.harmonics}")
    bad = [j for j in spec.trig_coords if not 0 <= j < nz]
    if bad:
        raise SpecError("trig_coords", f"{bad} out of range; valid indices into z = [x, u] are 0..{nz - 1}")
    if size(spec, nz) == 0:
        raise SpecError("library", "the library is empty")


def names(spec: LibrarySpec, nz: int, symbols: list[str] | None = None) -> list[str]:
    """Feature names in column order, pysindy style ("1", "x0 x1^2", "sin(1 x0)")."""
    sym = symbols or [f"x{i}" for i in range(nz)]

    def mono(t):
        if not t:
            return "1"
        counts = [(j, t.count(j)) for j in sorted(set(t))]
        return " ".join(sym[j] + (f"^{c}" if c > 1 else "") for j, c in counts)

    monos = [mono(t) for t in _monomials(spec, nz)]
    trig = [f"{fn}({h} {sym[j]})" for fn, h, j in _trig_terms(spec)]
    prods = [f"{m} {t}" for m in monos[int(spec.bias) :] for t in trig] if spec.products else []
    return monos + trig + prods


def _monomial_indices(spec: LibrarySpec, nz: int) -> list[np.ndarray]:
    """The non-constant monomials in column order, one [n_d, d] index array per degree d."""
    by_degree: dict[int, list[tuple[int, ...]]] = {}
    for t in _monomials(spec, nz):
        if t:
            by_degree.setdefault(len(t), []).append(t)
    return [np.asarray(ts, dtype=np.int32) for _, ts in sorted(by_degree.items())]


def features(spec: LibrarySpec, z: jax.Array) -> jax.Array:
    """Theta(z): z [..., nz] -> [..., P].

    One gather and d - 1 products per degree d, not one per column: the traced program
    (and its Jacobians, which iLQR on a surrogate takes) stays small for large libraries.
    Built with the feature axis leading (whole rows gathered), moved last at the end.
    """
    batch = z.shape[:-1]
    zt = jnp.moveaxis(z, -1, 0)  # [nz, ...]
    monos = [
        functools.reduce(jnp.multiply, (zt[idx[:, k]] for k in range(idx.shape[1])))
        for idx in _monomial_indices(spec, z.shape[-1])
    ]
    trig = []
    coords = np.asarray(spec.trig_coords, dtype=np.int32)
    if coords.size:
        for h in range(1, spec.harmonics + 1):
            a = h * zt[coords]  # sin and cos interleaved per coordinate
            trig.append(jnp.stack([jnp.sin(a), jnp.cos(a)], axis=1).reshape(2 * coords.size, *batch))
    blocks = ([jnp.ones((1, *batch), z.dtype)] if spec.bias else []) + monos + trig
    if spec.products and monos and trig:
        m, t = jnp.concatenate(monos), jnp.concatenate(trig)
        blocks.append((m[:, None] * t[None, :]).reshape(m.shape[0] * t.shape[0], *batch))
    return jnp.moveaxis(jnp.concatenate(blocks), 0, -1)


_ALIASES = {
    "cubic_trig": "poly3_trig",
    "quartic": "poly4",
    "quartic_trig": "poly4_trig",
    "cubic": "poly3",
    "quadratic": "poly2",
}


def parse(name: str, trig_coords: Tuple[int, ...], harmonics: int = 1) -> LibrarySpec:
    """A library name ("poly<d>[_nocross][_trig][_prod]" or an alias) -> LibrarySpec.

    Raises SpecError naming what would be valid.
    """
    full = _ALIASES.get(name, name)
    parts = full.split("_")
    head, flags = parts[0], set(parts[1:])
    valid = "'poly<d>' with optional _nocross, _trig, _prod (aliases: " + ", ".join(_ALIASES) + ")"
    if not head.startswith("poly") or not head[4:].isdigit() or not flags <= {"nocross", "trig", "prod"}:
        raise SpecError("library", f"unknown library {name!r}; valid: {valid}")
    trig = "trig" in flags or "prod" in flags
    if trig and not trig_coords:
        raise SpecError(
            "trig_coords",
            f"library {name!r} has trig terms but there are no "
            "trig coordinates (the model has no hinge joint; set them)",
        )
    return LibrarySpec(
        degree=int(head[4:]),
        cross_terms="nocross" not in flags,
        trig_coords=tuple(trig_coords) if trig else (),
        harmonics=harmonics,
        products="prod" in flags,
    )
