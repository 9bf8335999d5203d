"""Native float64 replay (mjx_surrogate.runs.native_replay) against mujoco.rollout."""

import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

from mjx_surrogate.runs import native_replay


def _rollout_states(model, substeps, x0, U):
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = x0[: model.nq], x0[model.nq :]
    init = np.zeros((1, mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS)))
    mujoco.mj_getState(model, data, init[0], mujoco.mjtState.mjSTATE_FULLPHYSICS)
    states, _ = mj_rollout.rollout(model, data, init, np.repeat(U, substeps, axis=0)[None])
    X = states[0, substeps - 1 :: substeps, 1 : 1 + model.nq + model.nv]
    return np.concatenate([x0[None], X])


def test_open_and_closed_loop_replay_match_mujoco_rollout(systems):
    s = systems("cartpole")
    m, T = s.mj_model, 20
    x0 = np.array([0.1, np.pi - 0.3, 0.0, 0.0])
    U = 0.5 * np.sin(np.arange(T))[:, None]
    X, applied = native_replay.replay(m, s.substeps, x0, U)
    np.testing.assert_array_equal(applied, U)
    np.testing.assert_allclose(X, _rollout_states(m, s.substeps, x0, U), rtol=0, atol=1e-12)
    # closed loop around the trajectory it produces: the feedback never acts
    K = np.random.default_rng(0).normal(size=(T, 1, 4))
    Xc, Uc = native_replay.replay(m, s.substeps, x0, U, X, K)
    np.testing.assert_array_equal(Xc, X)
    # around a shifted nominal the feedback acts: u_t = clip(U_t + K_t (x_t - X_t))
    Xs, Us = native_replay.replay(m, s.substeps, x0, U, X + 0.01, K, -np.ones(1), np.ones(1))
    np.testing.assert_allclose(Us[0], np.clip(U[0] + K[0] @ (x0 - X[0] - 0.01), -1, 1))
    assert np.all(np.abs(Us) <= 1) and not np.allclose(Xs, X)
    sq = lambda X, U: float(np.sum(X**2))  # noqa: E731
    costs = native_replay.replay_costs(sq, m, s.substeps, x0, U, X, K, None, None)
    assert costs["open_loop"] == costs["closed_loop"] == float(np.sum(X**2))
    assert costs["judged_by"] == "closed_loop"
