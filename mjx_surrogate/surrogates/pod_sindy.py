"""SINDy on POD coefficients (surrogate kind ``pod_sindy``), for black boxes with many states.

A SINDy library on the full state of a PDE grows as (nx + nu)^degree. The usual remedy
(e.g. Brunton and Kutz, "Data-Driven Science and Engineering", Ch. 7 and 12) is a proper
orthogonal decomposition of the training states: with the mean state x_m and the leading
r left singular vectors Phi [nx, r] of the centred states,

    a = Phi' (x - x_m),    a_next ~= Xi' theta([a, u]),    x_next ~= x_m + Phi a_next,

the library theta on r + nu coordinates (``surrogate.sindy.libraries``: the same names, one
model per library), fitted by the SINDy kind's least squares. What the r modes do not hold
of x_next is lost at every step: the model's error has a floor set by the rank.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct

from mjx_surrogate.surrogates import library
from mjx_surrogate.surrogates.library import LibrarySpec
from mjx_surrogate.surrogates.sindy import SindyModel
from mjx_surrogate.surrogates.sindy import fit as sindy_fit


@struct.dataclass
class PodSindyModel:
    mean: jax.Array  # [nx]
    basis: jax.Array  # [nx, r], orthonormal columns
    reduced: SindyModel  # on [a [r], u [nu]]

    def step(self, x: jax.Array, u: jax.Array) -> jax.Array:
        """x [nx], u [nu] -> x_next [nx] (any leading batch axes)."""
        a = (x - self.mean) @ self.basis
        return self.mean + self.reduced.step(a, u) @ self.basis.T


def pod_basis(x: jax.Array, rank: int) -> tuple[jax.Array, jax.Array, jax.Array]:
    """Mean [nx], the leading ``rank`` POD modes [nx, rank] of states x [N, nx], and the
    fraction of the centred states' energy they hold."""
    mean = jnp.mean(x, axis=0)
    _, s, vt = jnp.linalg.svd(x - mean, full_matrices=False)
    energy = s * s
    return mean, vt[:rank].T, jnp.sum(energy[:rank]) / jnp.maximum(jnp.sum(energy), jnp.finfo(x.dtype).tiny)


def fit(
    spec: LibrarySpec, x: jax.Array, u: jax.Array, x_next: jax.Array, rank: int, **sindy_options
) -> tuple[PodSindyModel, float]:
    """The model of the module docstring from transitions x, u, x_next [N, .]; returns it
    and the captured energy fraction."""
    mean, basis, captured = pod_basis(jnp.concatenate([x, x_next]), rank)
    a, a_next = (x - mean) @ basis, (x_next - mean) @ basis
    return PodSindyModel(mean, basis, sindy_fit(spec, a, u, a_next, **sindy_options)), float(captured)


def reduced_library_size(spec: LibrarySpec, rank: int, nu: int) -> int:
    return library.size(spec, rank + nu)
