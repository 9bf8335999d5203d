"""Third-party NumPy simulators as host black boxes: gymnasium's classic-control
environments (installed as a test dependency; they pull no MuJoCo), wrapped as users
would: the state set on the unwrapped environment, one ``step``, the new state read back.
D2C must reach a stated goal with the controls inside the environment's action bounds."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import mjx_surrogate as ms
from mjx_surrogate.control import chunked
from mjx_surrogate.runs import pipeline
from mjx_surrogate.systems.function import from_numpy

gymnasium = pytest.importorskip("gymnasium")

# id: (start, goal state of the task, horizon). MountainCarContinuous-v0: from its reset
# position, aiming just past its flag; the environment's own goal (position >=
# goal_position, 0.45) is checked below. Pendulum-v1 swings up from the command line as a
# kind of black box of its own (docs/extending.md, tests/test_extending.py).
CASES = {
    "MountainCarContinuous-v0": ([-0.5, 0.0], [0.5, 0.0], 200),
}


def wrap(env_id: str):
    """(the black box, a fresh environment for the replay)."""
    env = gymnasium.make(env_id).unwrapped
    env.reset(seed=0)

    def step(x, u):
        env.state = np.array(x, dtype=float)
        env.step(np.asarray(u, dtype=np.float32))
        return np.asarray(env.state, dtype=float)

    lo, hi = env.action_space.low.astype(float), env.action_space.high.astype(float)
    return from_numpy(step, 2, 1, 1.0, name=env_id, u_min=lo, u_max=hi), gymnasium.make(env_id).unwrapped


@pytest.mark.slow
@pytest.mark.parametrize("env_id", list(CASES))
def test_d2c_reaches_the_goal_on_a_gymnasium_numpy_simulator(env_id):
    system, replay_env = wrap(env_id)
    x0, goal, T = CASES[env_id]
    task = ms.make_task(
        x0=x0, x_goal=goal, Q=np.zeros((2, 2)), Q_f=100 * np.eye(2), R=0.01 * np.eye(1), T=T,
        u_min=system.u_min, u_max=system.u_max,
    )  # fmt: skip
    out = chunked.solve(
        system, task, jnp.zeros((T, 1)), jax.random.key(0), ms.ILQRParams(max_iter=300),
        ms.SysIdParams(1e-6, 1e-6, n_samples=6), "d2c",
    ).out  # fmt: skip
    metrics, X = pipeline.summary(out, system, task)
    U = np.asarray(out.U)
    assert metrics["goal"]["reached"], metrics["goal"]
    assert np.all(U >= system.u_min[0]) and np.all(U <= system.u_max[0]) and metrics["controls_within_limits"]
    assert metrics["status"] in ("converged", "stalled", "max_iter")
    assert (metrics["status"] == "converged") == bool(out.converged)
    # the controls replayed through the environment's own API, from the start
    replay_env.reset(seed=1)
    replay_env.state = np.array(x0, dtype=float)
    for u in U:
        replay_env.step(u.astype(np.float32))
    np.testing.assert_allclose(replay_env.state, np.asarray(X[-1]), rtol=1e-6, atol=1e-6)
    if hasattr(replay_env, "goal_position"):  # the environment's own success test
        assert float(np.max(np.asarray(X)[:, 0])) >= replay_env.goal_position
