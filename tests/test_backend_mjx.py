"""The MJX physics' batched step and Jacobians (mjx_surrogate/systems/backend_mjx.py)."""

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from mjx_surrogate.systems import backend_mjx

# A box pressed into the floor and pushed along it: its contacts keep the constraint solver
# busy in every substep, so the warmstart carried from one substep to the next matters.
BOX = """
<mujoco>
  <option timestep="0.005"/>
  <worldbody>
    <geom type="plane" size="2 2 .1"/>
    <body pos="0 0 0.1">
      <joint name="x" type="slide" axis="1 0 0"/>
      <joint name="z" type="slide" axis="0 0 1"/>
      <joint name="pitch" type="hinge" axis="0 1 0"/>
      <geom type="box" size="0.1 0.05 0.1" mass="1"/>
    </body>
  </worldbody>
  <actuator><motor joint="x"/><motor joint="pitch"/></actuator>
</mujoco>
"""


def _box(substeps=4):
    return backend_mjx.make_mjx_physics(mujoco.MjModel.from_xml_string(BOX), substeps)


def _points():
    X = jnp.array(
        [
            [0.0, -0.001, 0.05, 0.3, -0.2, 0.1],
            [0.2, -0.003, -0.02, -0.5, 0.1, 0.0],
            [0.1, -0.002, 0.0, 0.0, 0.0, 1.0],
        ]
    )
    U = jnp.array([[0.5, 0.0], [-1.0, 0.2], [0.0, -0.3]])
    return X, U


@pytest.mark.slow  # the fast tier has it on the pendulum (test_exported_step.py)
def test_batched_step_is_the_vmapped_step_to_round_off():
    """Bit for bit at XLA's default code generation; the suite's -O0 (conftest.py) moves the
    last bits of the two programs apart (2e-16 relative seen). One substep fewer: 0.19."""
    physics = _box()
    X, U = _points()
    np.testing.assert_allclose(
        physics.step_batch(X, U), jax.jit(jax.vmap(physics.step))(X, U), rtol=1e-13, atol=1e-15
    )


@pytest.mark.slow
def test_jacobians_are_jacfwd_through_the_step_with_contacts():
    """The substeps' warmstart is differentiated too: leaving its tangent out (a constant
    warmstart) changes entries of A by up to 0.65 on this box (checked)."""
    physics = _box()
    X, U = _points()
    A, B = physics.jacobians_batch(X, U)
    A_ref, B_ref = jax.jit(jax.vmap(jax.jacfwd(physics.step, argnums=(0, 1))))(X, U)
    assert A.shape == (3, 6, 6) and B.shape == (3, 6, 2)
    scale = float(jnp.max(jnp.abs(A_ref)))
    np.testing.assert_allclose(A, A_ref, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(B, B_ref, rtol=0, atol=1e-12 * scale)
    # and both are the step's own derivative: central differences of the float64 step
    h = 1e-6
    z = jnp.concatenate([X[0], U[0]])
    step = jax.jit(lambda z: physics.step(z[:6], z[6:]))
    J = jnp.stack([(step(z + h * e) - step(z - h * e)) / (2 * h) for e in jnp.eye(8)], axis=1)
    np.testing.assert_allclose(jnp.concatenate([A[0], B[0]], axis=1), J, rtol=0, atol=1e-6 * scale)
