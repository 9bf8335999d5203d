"""The jitted D2C against an independent NumPy + native mujoco.rollout implementation."""

import jax.numpy as jnp
import numpy as np
import pytest
import reference_d2c_numpy as d2c_numpy

from mjx_surrogate.control.d2c import solve_d2c
from mjx_surrogate.control.ilqr import ILQRParams
from mjx_surrogate.identification.sysid import SysIdParams
from mjx_surrogate.runs.config import Config, SystemConfig, TaskConfig
from mjx_surrogate.runs.resolution import resolve


@pytest.mark.slow  # over 5 s: the fast tier's budget
def test_jax_d2c_matches_numpy_reference_on_pendulum():
    res = resolve(
        Config(system=SystemConfig(name="pendulum", backend="native"), task=TaskConfig(preset="pendulum_d2c"))
    )
    s, task = res.system, res.task
    U0 = np.zeros((task.T, 1))
    ref = d2c_numpy.solve(
        d2c_numpy.NativeStepper(s.mj_model, s.substeps),
        np.asarray(task.x0),
        U0,
        *(np.asarray(a) for a in (task.x_goal, task.Q, task.Q_f, task.R)),
        max_iter=100,
        rel_tol=1e-7,
    )
    import jax

    out = solve_d2c(
        s, task, jnp.asarray(U0), jax.random.key(0), ILQRParams(rel_tol=1e-7), SysIdParams(n_samples=10)
    )
    assert float(out.cost) == pytest.approx(ref["cost"], rel=1e-4)
    np.testing.assert_allclose(np.asarray(out.U), ref["U"], atol=2e-2)
