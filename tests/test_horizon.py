"""Identification error against the horizon (mjx_surrogate/analysis/horizon.py): exact on a linear
system in both modes; the gains keep an unstable system's rollouts close."""

import jax.numpy as jnp
import numpy as np

from mjx_surrogate.analysis import horizon
from mjx_surrogate.trajectory import simulate

A_UNSTABLE = jnp.asarray([[1.2, 0.1], [0.0, 1.1]])
B = jnp.asarray([[0.0], [1.0]])


class LinearBlackBox:
    """A hashable stand-in for a System: ``step`` and ``mesh`` are all the module uses."""

    mesh = None

    @staticmethod
    def step(x, u):
        return A_UNSTABLE @ x + B @ u


def test_exact_on_a_linear_system_and_the_gains_keep_the_rollouts_close():
    T = 25
    U = jnp.zeros((T, 1))
    X = simulate(LinearBlackBox.step, jnp.array([1.0, -0.5]), U)
    K = jnp.broadcast_to(jnp.asarray([[-6.3, -1.5]]), (T, 1, 2))  # eigenvalues of A + B K: 0.5, 0.3
    assert np.max(np.abs(np.linalg.eigvals(np.asarray(A_UNSTABLE + B @ K[0])))) < 1
    A_ref = jnp.broadcast_to(A_UNSTABLE, (T, 2, 2))
    B_ref = jnp.broadcast_to(B, (T, 2, 1))
    import jax

    out = horizon.identification_errors(
        LinearBlackBox(), X, U, K, A_ref, B_ref, jax.random.key(0), 40,
        jnp.full(2, 0.01), jnp.full(1, 0.01), -jnp.inf * jnp.ones(1), jnp.inf * jnp.ones(1),
    )  # fmt: skip
    assert out.error.shape == (2, T) and out.spread.shape == (2, T + 1)
    assert float(jnp.max(out.error)) < 1e-8  # linear: every mode exact, at every t
    assert float(jnp.max(out.closed_loop_error)) < 1e-8
    # open loop the perturbations grow like 1.2^t; under the gains they decay
    assert float(out.spread[0, -1]) > 50 * float(out.spread[0, 0])
    assert float(out.spread[1, -1]) < float(out.spread[1, 0])
