"""D2C-MPC with its models carried across replans (mjx_surrogate/control/mpc_reuse.py)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mjx_surrogate.control import mpc, mpc_reuse
from mjx_surrogate.control.ilqr import ILQRParams
from mjx_surrogate.errors import ConfigError
from tests.test_mpc import SID, A, B, H, N, _linear, _task

CARRY = mpc_reuse.D2CPlannerSettings(reuse_tol=0.1, reuse_max=3)


def _episodes(max_iter, settings=CARRY):
    params = ILQRParams(max_iter=max_iter)
    common = dict(key=jax.random.key(0), steps=N, params=params, sysid=SID)
    plain = mpc.receding_horizon(_linear(), _task(), jnp.zeros((H, 1)), **common)
    carried = mpc_reuse.carried_receding_horizon(
        _linear(), _task(), jnp.zeros((H, 1)), settings=settings, **common
    )
    return plain, carried


def test_on_a_linear_system_the_carried_models_give_the_same_loop_with_fewer_identifications():
    """A linear map's model is exact wherever it was identified: with one iteration per
    replan, replans 1-3 run on the carried model and replan 4 identifies again (reuse_max
    3), and the closed loop is D2C-MPC's own to round-off; with three iterations the first
    iteration's identification is saved and the second's kept."""
    plain, carried = _episodes(1)
    np.testing.assert_allclose(np.asarray(carried.X), np.asarray(plain.X), atol=1e-9)
    assert float(carried.cost) == pytest.approx(float(plain.cost), rel=1e-9)
    per_replan = np.asarray(carried.identified).sum(axis=1)
    np.testing.assert_array_equal(per_replan, (np.arange(N) % 4 == 0).astype(int))
    np.testing.assert_array_equal(np.asarray(plain.identified).sum(axis=1), np.ones(N))

    plain, carried = _episodes(3)
    np.testing.assert_allclose(np.asarray(carried.X), np.asarray(plain.X), atol=1e-9)
    np.testing.assert_array_equal(np.asarray(carried.identified)[1:, 0], np.zeros(N - 1))
    np.testing.assert_array_equal(np.asarray(carried.identified)[1:, 1], np.ones(N - 1))


def _replan_from(plan, max_iter=1):
    replan = mpc_reuse.reuse_replan(_linear(), _task(), ILQRParams(max_iter=max_iter), SID, CARRY)
    return jax.jit(lambda x, p: replan(x, p, jax.random.key(1), 0))(jnp.array([1.0, 0.0]), plan)


def _previous_plan(A_model):
    """A plan whose model is ``A_model`` (B exact), identified one replan ago, of a nominal
    that the new warm start leaves (its states 0.1 off)."""
    U = jnp.full((H, 1), -0.5)
    X = [jnp.array([0.9, 0.1])]
    for u in U:
        X.append(jnp.asarray(A) @ X[-1] + jnp.asarray(B) @ u)
    X = jnp.stack(X)
    As = jnp.broadcast_to(jnp.asarray(A_model), (H, 2, 2))
    Bs = jnp.broadcast_to(jnp.asarray(B), (H, 2, 1))
    return mpc_reuse.CarriedPlan(U, X, jnp.zeros((H, 1, 2)), As, Bs, X, U, jnp.zeros((H,)), jnp.ones((H,)))


def test_a_carried_model_that_no_longer_predicts_is_identified_again():
    """The same warm start, the same nominal change: the exact model is carried over
    (nothing identified), a model whose A is off by 0.3 on the velocity coupling fails the
    prediction test and the replan identifies; the age counts replans without one."""
    kept, (_, _, identified) = _replan_from(_previous_plan(A))
    assert int(identified[0]) == 0 and float(kept.age[0]) == 1.0
    wrong = A + np.array([[0.0, 0.3], [0.0, 0.0]])
    fresh, (_, _, identified) = _replan_from(_previous_plan(wrong))
    assert int(identified[0]) == 1 and float(fresh.age[0]) == 0.0
    np.testing.assert_allclose(np.asarray(fresh.A), np.broadcast_to(A, (H, 2, 2)), atol=1e-9)


def test_the_prediction_test_and_the_repeated_stages():
    """prediction_fits against the error it states (float64 NumPy), on both sides of the
    threshold; consistent_nominal leaves the stages the black box took and makes the
    repeated last stage exact, so that it neither fails the test nor moves in the update."""
    rng = np.random.default_rng(0)
    As, Bs = rng.normal(size=(H, 2, 2)), rng.normal(size=(H, 2, 1))
    dU = rng.normal(size=(H, 1))
    dX = [rng.normal(size=2)]
    for t in range(H):
        dX.append(As[t] @ dX[-1] + Bs[t] @ dU[t])
    dX = np.array(dX)
    noise = rng.normal(size=(H, 2))
    bent = dX.copy()
    bent[1:] += 0.05 * noise
    e = bent[1:] - np.einsum("tij,tj->ti", As, bent[:-1]) - np.einsum("tij,tj->ti", Bs, dU)
    ratio = np.sqrt(np.sum(e**2) / np.sum(bent[1:] ** 2))
    fits = lambda d, tol: bool(mpc_reuse.prediction_fits(As, Bs, d, dU, tol))  # noqa: E731
    assert fits(dX, 1e-9)
    assert fits(bent, 1.01 * ratio) and not fits(bent, 0.99 * ratio)
    assert not fits(np.full_like(dX, np.nan), 0.5)
    # an error at the stages between knots (interpolated models) is not the carried model's
    knots = np.zeros(H)
    knots[::3] = 1.0
    between = [dX[0]]
    for t in range(H):
        between.append(As[t] @ between[-1] + Bs[t] @ dU[t] + (1 - knots[t]) * 0.5 * noise[t])
    between = np.array(between)
    assert not fits(between, 0.05)
    assert bool(mpc_reuse.prediction_fits(As, Bs, between, dU, 1e-9, knots))

    X_model = rng.normal(size=(H + 1, 2))
    X_model[-1] = X_model[-2]  # the row a shift repeats
    U_model = rng.normal(size=(H, 1))
    X = X_model + dX
    U = U_model + dU
    X[-1] += 1.0  # the new nominal's last state, of no stage the model saw
    out = np.asarray(mpc_reuse.consistent_nominal(As, Bs, X, U, X_model, U_model))
    np.testing.assert_array_equal(out[:-1], X_model[:-1])
    d = X - out
    np.testing.assert_allclose(d[-1], As[-1] @ d[-2] + Bs[-1] @ dU[-1], atol=1e-12)


def test_settings_refused():
    with pytest.raises(ConfigError, match="reuse_tol"):
        mpc_reuse.D2CPlannerSettings(reuse_tol=1.0).check()
    with pytest.raises(ConfigError, match="reuse_max"):
        mpc_reuse.D2CPlannerSettings(reuse_max=0).check()


def test_a_plan_already_optimal_on_the_carried_model_is_kept_without_identifying():
    """Replanning from the state a replan just solved, with its plan and model: the
    carried model passes its test, its first iteration finds no step, and the replan stops
    there as converged, identifying nothing (the chain's secant reuse alone would distrust
    the carried model and identify at a second iteration)."""
    first = mpc_reuse.first_carried_plan(jnp.zeros((H, 1)), jnp.array([1.0, 0.0]), CARRY.reuse_max)
    solved, _ = _replan_from(first, max_iter=10)
    again, (_, iterations, identified) = _replan_from(solved, max_iter=10)
    assert int(iterations) == 1 and not np.any(np.asarray(identified))
    np.testing.assert_allclose(np.asarray(again.U), np.asarray(solved.U), atol=1e-9)


@pytest.mark.slow
def test_the_mpc_kind_carries_the_models_in_its_batches_and_in_the_wall_clock_loop(tmp_path):
    """``--mpc.d2c.reuse_tol``: the smoke preset's D2C-MPC with carried models simulates
    fewer black-box steps per control step than with a model identified at every replan, at
    a closed-loop cost within 1 % of it; its wall-clock loop (the clock slowed so that no
    plan is late), one episode at a time where the batch is ``vmap``ped, gives the batch's
    closed loops."""
    import dataclasses
    import json
    import os

    from configs.smoke_mpc import CONFIG
    from experiments.run import run
    from mjx_surrogate.runs.realtime_rows import label

    def rows(reuse_tol, realtime):
        cfg = dataclasses.replace(
            CONFIG,
            mpc=dataclasses.replace(
                CONFIG.mpc,
                controllers=("d2c",),
                realtime=realtime,
                realtime_speed=0.25,
                process_noise=(0.01,),
            ),
            experiment=dataclasses.replace(CONFIG.experiment, out_dir=str(tmp_path), video=False),
            extensions={**CONFIG.extensions, "mpc.d2c": {"reuse_tol": reuse_tol}},
        )
        folder = run(cfg, name=f"reuse{reuse_tol}")
        with open(os.path.join(folder, "metrics.json")) as f:
            return json.load(f)["mpc_rows"], np.load(os.path.join(folder, "arrays.npz"))

    (own,), _ = rows(0.0, False)
    (carried, late), arrays = rows(0.5, True)
    assert (carried["controller"], late["controller"]) == ("D2C-MPC", label("D2C-MPC"))
    assert carried["black_box_steps_per_control_step"] < own["black_box_steps_per_control_step"]
    np.testing.assert_allclose(carried["costs"], own["costs"], rtol=0.01)
    assert late["plans_late_ticks_max"] == 0
    np.testing.assert_allclose(arrays[late["arrays"]["X"]], arrays[carried["arrays"]["X"]], atol=1e-9)
