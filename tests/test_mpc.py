"""Receding-horizon control (mjx_surrogate/control/mpc.py) against closed forms and counted calls."""

import os
import re
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mjx_surrogate import progress
from mjx_surrogate.control import mpc, mpc_sampling
from mjx_surrogate.control.episode import POLLS_PER_EPISODE
from mjx_surrogate.control.ilqr import ILQRParams
from mjx_surrogate.identification import sysid as sid
from mjx_surrogate.identification.sysid import SysIdParams
from mjx_surrogate.systems.function import from_jax, from_numpy
from mjx_surrogate.tasks import make_task

A = np.array([[1.0, 0.1], [0.0, 1.0]])  # a double integrator, dt 0.1
B = np.array([[0.005], [0.1]])
Q, Q_F, R = np.diag([1.0, 0.1]), np.diag([10.0, 1.0]), np.diag([0.01])
H, N = 10, 30
SID = SysIdParams(n_samples=6)


def _linear(A=A, B=B):
    A_, B_ = jnp.asarray(A), jnp.asarray(B)
    return from_jax(lambda x, u: A_ @ x + B_ @ u, 2, 1, 0.1)


def _task(x0=(1.0, 0.0)):
    return make_task(x0, (0.0, 0.0), Q, Q_F, R, H)


def _lqr_first_gain(A, B, horizon):
    """K_0 of the finite-horizon LQR (float64 NumPy Riccati recursion)."""
    P = Q_F
    for _ in range(horizon):
        K = -np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)
        P = Q + A.T @ P @ (A + B @ K)
    return K


@pytest.mark.parametrize("controller", [pytest.param("jacfwd", marks=pytest.mark.slow), "d2c"])
def test_mpc_on_a_linear_system_is_the_receding_horizon_lqr(controller):
    """Unconstrained linear-quadratic: every replan is the horizon-H LQR, so the closed loop
    is x_{n+1} = (A + B K_0) x_n; D2C identifies the linear map to round-off."""
    r = mpc.receding_horizon(
        _linear(),
        _task(),
        jnp.zeros((H, 1)),
        key=jax.random.key(0),
        steps=N,
        params=ILQRParams(max_iter=3),
        sysid=SID,
        controller=controller,
    )
    K0 = _lqr_first_gain(A, B, H)
    X = [np.array([1.0, 0.0])]
    for _ in range(N):
        X.append((A + B @ K0) @ X[-1])
    X = np.array(X)
    np.testing.assert_allclose(np.asarray(r.X), X, atol=1e-8)
    np.testing.assert_allclose(np.asarray(r.U), X[:-1] @ K0.T, atol=1e-8)
    J = (
        sum(0.5 * x @ Q @ x + 0.5 * u @ R @ u for x, u in zip(X[:-1], X[:-1] @ K0.T))
        + 0.5 * X[-1] @ Q_F @ X[-1]
    )
    assert float(r.cost) == pytest.approx(J, rel=1e-8)
    assert r.plan_cost.shape == (N,) and np.all(np.asarray(r.iterations) >= 1)


@pytest.mark.slow
@pytest.mark.parametrize("planner", ["d2c", "surrogate"])
def test_a_horizon_that_shrinks_to_the_tasks_end_is_the_finite_horizon_lqr(planner):
    """A task that ends 15 steps after the episode's start (deadline 15), planned over
    H = 10: the plan at step n ends at stage h_n = min(H, 15 - n) with the terminal weight
    there, so u_n = K_0 of the horizon-h_n LQR (float64 NumPy); once the end is within the
    horizon the closed loop is the finite-horizon LQR of the task itself. The receding
    horizon's loop (every plan H steps) differs from it."""
    N = 15
    task = _task().replace(deadline=N)
    U0, key, params = jnp.zeros((H, 1)), jax.random.key(0), ILQRParams(max_iter=3)
    if planner == "d2c":
        r = mpc.receding_horizon(_linear(), task, U0, key=key, steps=N, params=params, sysid=SID)
    else:
        model = _LinearModel(jnp.asarray(A), jnp.asarray(B))
        r = mpc.surrogate_mpc(model, task, U0, plant=_linear(), key=key, steps=N, params=params)
    X = [np.array([1.0, 0.0])]
    U = []
    for n in range(N):
        U.append(_lqr_first_gain(A, B, min(H, N - n)) @ X[-1])
        X.append(A @ X[-1] + B @ U[-1])
    np.testing.assert_allclose(np.asarray(r.X), np.array(X), atol=1e-8)
    np.testing.assert_allclose(np.asarray(r.U), np.array(U), atol=1e-8)
    receding = mpc.receding_horizon(_linear(), _task(), U0, key=key, steps=N, params=params, sysid=SID)
    assert np.max(np.abs(np.asarray(receding.U) - np.array(U))) > 1e-3


@pytest.mark.parametrize("planner", ["d2c", "surrogate"])
def test_between_replans_the_plant_steps_under_the_plans_feedback_policy(planner):
    """Replanning every 3rd of 30 steps under process noise 0.05 on a linear system: each
    replan is the horizon-H LQR from the measured state, and the plant then steps under its
    time-varying gains, u_{n+j} = U[j] + K[j] (x - X[j]) = K_j x for j = 0, 1, 2 (float64
    NumPy Riccati recursion; the noise of step n drawn from the n-th of the episode's keys,
    as at every step)."""
    key, w, r = jax.random.key(4), 0.05, 3
    params = ILQRParams(max_iter=3)
    if planner == "d2c":
        res = mpc.receding_horizon(
            _linear(),
            _task(),
            jnp.zeros((H, 1)),
            key=key,
            steps=N,
            params=params,
            sysid=SID,
            process_noise=w,
            replan_every=r,
        )
    else:
        model = _LinearModel(jnp.asarray(A), jnp.asarray(B))
        res = mpc.surrogate_mpc(
            model,
            _task(),
            jnp.zeros((H, 1)),
            plant=_linear(),
            key=key,
            steps=N,
            params=params,
            process_noise=w,
            replan_every=r,
        )
    P, gains = Q_F, []
    for _ in range(H):  # K_{H-1}, ..., K_0
        K = -np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)
        P = Q + A.T @ P @ (A + B @ K)
        gains.append(K)
    gains = gains[::-1]
    keys = jax.random.split(key, N)
    X = [np.array([1.0, 0.0])]
    for n in range(N):
        u = gains[n % r] @ X[-1]
        noise = w * np.asarray(jax.random.normal(jax.random.split(keys[n])[1], (2,), jnp.float64))
        X.append(A @ X[-1] + B @ u + noise)
    np.testing.assert_allclose(np.asarray(res.X), np.array(X), atol=1e-7)
    assert res.plan_cost.shape == res.iterations.shape == (N // r,)
    with pytest.raises(ValueError, match="replan_every: a divisor of the 30 steps, got 4"):
        mpc.receding_horizon(
            _linear(), _task(), jnp.zeros((H, 1)), key=key, steps=N, params=params, sysid=SID, replan_every=4
        )


class _LinearModel(NamedTuple):
    """A differentiable surrogate as the surrogates are: a pytree with step(x, u)."""

    A: jax.Array
    B: jax.Array

    def step(self, x, u):
        return self.A @ x + self.B @ u


def test_surrogate_mpc_with_the_true_model_is_the_receding_horizon_lqr():
    """Planning on a surrogate that is the plant's own linear map gives the LQR closed loop;
    the plant, not the surrogate, moves the state (a wrong surrogate's plans still land on
    the plant's steps)."""
    plant = _linear()
    exact = _LinearModel(jnp.asarray(A), jnp.asarray(B))
    r = mpc.surrogate_mpc(
        exact,
        _task(),
        jnp.zeros((H, 1)),
        plant=plant,
        key=jax.random.key(0),
        steps=N,
        params=ILQRParams(max_iter=3),
    )
    K0 = _lqr_first_gain(A, B, H)
    X = [np.array([1.0, 0.0])]
    for _ in range(N):
        X.append((A + B @ K0) @ X[-1])
    np.testing.assert_allclose(np.asarray(r.X), np.array(X), atol=1e-8)
    wrong = _LinearModel(jnp.asarray(A), jnp.asarray(3.0 * B))
    w = mpc.surrogate_mpc(
        wrong,
        _task(),
        jnp.zeros((H, 1)),
        plant=plant,
        key=jax.random.key(0),
        steps=N,
        params=ILQRParams(max_iter=3),
    )
    Xw, Uw = np.asarray(w.X), np.asarray(w.U)
    np.testing.assert_allclose(Xw[1:], Xw[:-1] @ A.T + Uw @ B.T, atol=1e-12)
    assert not np.allclose(Xw, np.array(X), atol=1e-3)


def test_tracking_is_the_tvlqr_loop_with_the_planners_noise_draws():
    """TVLQR tracking against a NumPy loop u_n = clip(U_ref[n] + K[n] (x_n - X_ref[n])),
    and its process noise: the same draws as a replanning episode from the same key."""
    rng = np.random.default_rng(0)
    X_ref, U_ref = rng.normal(size=(N + 1, 2)), rng.normal(size=(N, 1))
    K = rng.normal(size=(N, 1, 2)) * 0.3
    task = _task().replace(u_min=jnp.array([-0.8]), u_max=jnp.array([0.8]))
    r = mpc.tracking(
        task, jnp.asarray(X_ref), jnp.asarray(U_ref), jnp.asarray(K), plant=_linear(), key=jax.random.key(3)
    )
    x, X, U = np.array([1.0, 0.0]), [], []
    for n in range(N):
        u = np.clip(U_ref[n] + K[n] @ (x - X_ref[n]), -0.8, 0.8)
        X.append(x), U.append(u)
        x = A @ x + B @ u
    np.testing.assert_allclose(np.asarray(r.X), np.array(X + [x]), atol=1e-12)
    np.testing.assert_allclose(np.asarray(r.U), np.array(U), atol=1e-12)
    key, noise = jax.random.key(5), 0.1
    tr = mpc.tracking(
        task,
        jnp.asarray(X_ref),
        jnp.asarray(U_ref),
        jnp.asarray(K),
        plant=_linear(),
        key=key,
        process_noise=noise,
    )
    rh = mpc.receding_horizon(
        _linear(),
        _task(),
        jnp.zeros((H, 1)),
        key=key,
        steps=N,
        params=ILQRParams(max_iter=2),
        sysid=SID,
        process_noise=noise,
        controller="jacfwd",
    )
    residual = lambda e: np.asarray(e.X[1:]) - np.asarray(e.X[:-1]) @ A.T - np.asarray(e.U) @ B.T  # noqa: E731
    np.testing.assert_allclose(residual(tr), residual(rh), atol=1e-12)
    assert 0.05 < residual(tr).std() < 0.2


def test_the_plant_is_stepped_with_the_episodes_noise_and_the_model_is_not_the_plant():
    """A heavier plant than the model: every closed-loop step is the plant's step plus the
    episode's process noise, drawn from its key; zero noise leaves the plant's step exact."""
    model, plant = _linear(), _linear(B=0.5 * B)
    step = lambda x, u: A @ x + 0.5 * B @ u  # noqa: E731
    task, U0, params = _task(), jnp.zeros((H, 1)), ILQRParams(max_iter=3)
    run = lambda noise, key: mpc.receding_horizon(  # noqa: E731
        model,
        task,
        U0,
        key=key,
        steps=N,
        params=params,
        sysid=SID,
        process_noise=noise,
        controller="jacfwd",
        plant=plant,
    )
    quiet = run(0.0, jax.random.key(1))
    X, U = np.asarray(quiet.X), np.asarray(quiet.U)
    np.testing.assert_allclose(X[1:], np.array([step(x, u) for x, u in zip(X[:-1], U)]), atol=1e-14)
    K0 = _lqr_first_gain(A, B, H)  # the model's gain on the plant: not the plant's own LQR
    np.testing.assert_allclose(U, X[:-1] @ K0.T, atol=1e-8)

    noisy, again, other = (
        run(0.01, jax.random.key(1)),
        run(0.01, jax.random.key(1)),
        run(0.01, jax.random.key(2)),
    )
    Xn, Un = np.asarray(noisy.X), np.asarray(noisy.U)
    w = Xn[1:] - np.array([step(x, u) for x, u in zip(Xn[:-1], Un)])
    assert 0.005 < w.std() < 0.02 and abs(w.mean()) < 0.005  # 60 draws of N(0, 0.01^2)
    np.testing.assert_array_equal(np.asarray(again.X), Xn)
    assert not np.allclose(np.asarray(other.X), Xn)


@pytest.mark.slow
@pytest.mark.parametrize(
    "every,replan_every,scheme",
    [(1, 1, "central_difference"), (4, 1, "central_difference"), (1, 5, "central_difference")]
    + [(1, 1, "forward_difference")],
)
def test_black_box_steps_are_the_calls_the_black_box_received(every, replan_every, scheme):
    """A NumPy black box counts the rows it is asked to step: the episode's calls are the
    plant's N steps plus black_box_steps per replan; identified at every 4th step of the
    horizon (and its last: 4 of 10 steps), each identification steps 4/10 as many rows,
    and on a linear system the interpolated models are the exact ones: the same LQR loop;
    forward differences step (n + 1) rows per stage where central ones step 2 n."""
    calls = []

    def step(x, u):
        calls.append(len(x))
        return x @ A.T + u @ B.T

    system = from_numpy(step, 2, 1, 0.1, vectorized=True)
    params, sysid = ILQRParams(max_iter=3), SID.replace(every=every, scheme=scheme)
    r = mpc.receding_horizon(
        system,
        _task(),
        jnp.zeros((H, 1)),
        key=jax.random.key(0),
        steps=5,
        params=params,
        sysid=sysid,
        replan_every=replan_every,
    )
    per_replan = mpc.black_box_steps(r, H, params.n_alphas, sysid)
    assert per_replan.shape == (5 // replan_every,) and np.all(per_replan > 0)
    assert sum(calls) == 5 + int(per_replan.sum()), (sum(calls), per_replan)
    assert np.all(np.asarray(r.identified) <= 1)  # never an every-step model
    knots = 10 if every == 1 else 4
    n = SID.n_samples
    rows = n + 1 if scheme == "forward_difference" else 2 * n  # per stage; the reference's 2 n
    steps, reference = sid.steps_per_identification(sysid, H), sid.steps_per_identification(SID, H)
    assert 10 * 2 * n * steps == knots * rows * reference
    if replan_every == 1:
        K0 = _lqr_first_gain(A, B, H)
        X = [np.array([1.0, 0.0])]
        for _ in range(5):
            X.append((A + B @ K0) @ X[-1])
        np.testing.assert_allclose(np.asarray(r.X), np.array(X), atol=1e-8)


@pytest.mark.slow
def test_episodes_batch_by_vmap_and_a_new_start_does_not_recompile():
    system, task, U0, params = _linear(), _task(), jnp.zeros((H, 1)), ILQRParams(max_iter=3)
    one = lambda x0, key: mpc.receding_horizon(  # noqa: E731
        system, task.replace(x0=x0), U0, key=key, steps=N, params=params, sysid=SID, process_noise=0.01
    )
    x0s = jnp.array([[1.0, 0.0], [-0.5, 0.2], [0.3, -1.0]])
    keys = jax.random.split(jax.random.key(3), 3)
    batch = jax.vmap(one)(x0s, keys)
    before = mpc.receding_horizon._cache_size()
    singles = [one(x0s[i], keys[i]) for i in range(3)]
    assert mpc.receding_horizon._cache_size() == before + 1  # one program for every start
    for i, s in enumerate(singles):
        np.testing.assert_allclose(np.asarray(batch.X[i]), np.asarray(s.X), atol=1e-10)
        assert float(batch.cost[i]) == pytest.approx(float(s.cost), rel=1e-9)


def test_every_episode_function_takes_all_but_its_plan_by_name():
    """What is planned on, the task and the first plan positionally, the rest keyword-only:
    a positional key or step count is refused (TypeError) instead of landing in a wrong slot."""
    import inspect

    from mjx_surrogate.control import episode, mpc_hybrid, mpc_online

    leading = {
        mpc.receding_horizon: ["system", "task", "U0"],
        mpc.surrogate_mpc: ["model", "task", "U0"],
        mpc.tracking: ["task", "X_ref", "U_ref", "K"],
        mpc_sampling.sampling_mpc: ["system", "task", "U0"],
        mpc_hybrid.hybrid_mpc: ["system", "task", "U0"],
        mpc_online.refitted_sindy_mpc: ["model", "offline", "task", "U0"],
        mpc_online.refitted_mlp_mpc: ["model", "offline", "task", "U0"],
        episode.episode: ["replan"],
    }
    for fn, names in leading.items():
        params = list(inspect.signature(fn).parameters.values())
        positional = [p.name for p in params if p.kind is not inspect.Parameter.KEYWORD_ONLY]
        assert positional == names, (fn, positional)
        assert {"key", "steps"} <= {p.name for p in params if p.kind is inspect.Parameter.KEYWORD_ONLY} or (
            fn is mpc.tracking
        )
    with pytest.raises(TypeError):
        mpc.receding_horizon(_linear(), _task(), jnp.zeros((H, 1)), jax.random.key(0), 2)


def test_an_unknown_controller_is_refused():
    with pytest.raises(ValueError, match="controller: one of d2c, jacfwd, finite_difference"):
        mpc.receding_horizon(
            _linear(), _task(), jnp.zeros((H, 1)), key=jax.random.key(0), steps=2, controller="mppi"
        )


@pytest.mark.slow
def test_d2c_mpc_swings_the_mujoco_pendulum_up_as_the_oracles_mpc_does():
    """docs/mpc.md's "From Python" as written (native MuJoCo pendulum from hanging down,
    horizon 40 steps of 0.1 s, a replan's parameters from ``ms.mpc_params``, 80 control
    steps): shapes as the page states; D2C-MPC ends at rest upright with the closed-loop
    cost of the finite-difference oracle's MPC to 1e-4."""
    text = open(os.path.join(os.path.dirname(os.path.dirname(__file__)), "docs", "mpc.md")).read()
    (block,) = re.findall(r"## From Python\n\n```python\n(.*?)```", text, flags=re.S)
    namespace: dict = {}
    exec(compile(block, "docs/mpc.md", "exec"), namespace)
    d2c, system, task = namespace["episode"], namespace["system"], namespace["task"]
    params = namespace["params"].replace(max_iter=5)
    oracle = mpc.receding_horizon(
        system,
        task,
        jnp.zeros((40, 1)),
        key=jax.random.key(0),
        steps=80,
        params=params,
        sysid=namespace["sysid"],
        controller="finite_difference",
    )
    assert d2c.X.shape == (81, 2) and d2c.U.shape == (80, 1)
    assert (namespace["sysid"].n_samples, namespace["sysid"].design) == (3, "orthogonal")
    assert np.max(np.abs(np.asarray(d2c.X[-1]))) < 1e-3  # at rest upright (theta = 0)
    assert float(d2c.cost) == pytest.approx(float(oracle.cost), rel=1e-4)


def _numpy_policy(x0, X, U, K):
    """u_t = U_t + K_t (x_t - X_t) on the double integrator, float64 NumPy."""
    x, us = np.asarray(x0, float), []
    for t in range(len(U)):
        us.append(U[t] + K[t] @ (x - X[t]))
        x = A @ x + B @ us[-1]
    return np.array(us)


def test_a_replan_starts_from_the_cheaper_of_the_previous_policy_and_its_controls():
    """A replan's first nominal: the previous plan's policy rolled out from the measured
    state where that is cheaper than its controls alone, else those."""
    from mjx_surrogate.control.d2c import problem

    U = 0.1 * np.sin(np.arange(H))[:, None]
    X = np.zeros((H + 1, 2))
    for t in range(H):  # the plan predicted from the origin; the state measured is elsewhere
        X[t + 1] = A @ X[t] + B @ U[t]
    K = np.tile(_lqr_first_gain(A, B, H), (H, 1, 1))  # stabilising gains
    x = np.array([1.0, 0.0])
    prob = problem(_linear(), _task(x), SID, "d2c")
    plan = mpc.Plan(jnp.asarray(U), jnp.asarray(X), jnp.asarray(K))
    start = mpc.warm_start(prob, plan, ILQRParams(), jax.random.key(0)).solver
    np.testing.assert_allclose(np.asarray(start.U), _numpy_policy(x, X, U, K), atol=1e-12)
    wild = plan._replace(K=jnp.asarray(-1e3 * K))  # a policy far costlier than its controls
    start = mpc.warm_start(prob, wild, ILQRParams(), jax.random.key(0)).solver
    np.testing.assert_allclose(np.asarray(start.U), U, atol=1e-12)
    blown = mpc.Plan(jnp.full((H, 1), 1e300), jnp.asarray(X), jnp.asarray(K))  # both rollouts overflow
    blown_start = mpc.warm_start(prob, blown, ILQRParams(), jax.random.key(0)).solver
    assert not np.isfinite(float(blown_start.cost)) and np.all(np.asarray(blown_start.U) == 1e300)
    x_next = x
    for t in range(H):  # the nominal is the controls' own rollout
        x_next = A @ x_next + B @ U[t]
    np.testing.assert_allclose(np.asarray(start.X[-1]), x_next, atol=1e-12)


class _StopAt:
    """A stand-in progress bar that requests a stop once ``at`` control steps have begun."""

    def __init__(self, at: int):
        self.at, self.n, self.seen = at, 0, []

    def refresh(self):
        self.seen.append(self.n)
        if self.n >= self.at:
            progress.request_stop()


@pytest.mark.slow
@pytest.mark.parametrize("controller", ["d2c", "sampling"])
def test_a_stop_inside_a_batch_of_episodes_skips_its_remaining_steps(controller):
    """The meter counts each control step and a stop request skips the rest of every
    episode of the vmapped batch: no black-box call after it, NaN rows; with no stop the
    meter changes no number and switching it on does not recompile."""
    keys = jax.random.split(jax.random.key(1), 3)
    calls = []

    def f(x, u):  # the black box on the host: its calls counted
        calls.append(1)
        return A @ x + B @ u

    plant, task, U0 = from_numpy(f, 2, 1, 0.1), _task(), jnp.zeros((H, 1))

    def batch(meter):
        if controller == "sampling":
            one = lambda k: mpc_sampling.sampling_mpc(  # noqa: E731
                plant,
                task,
                U0,
                key=k,
                steps=N,
                settings=mpc_sampling.SamplingSettings(samples=8),
                hyper=mpc_sampling.hyper(0.5),
                progress=meter,
            )
        else:
            one = lambda k: mpc.receding_horizon(  # noqa: E731
                plant, task, U0, key=k, steps=N, params=ILQRParams(max_iter=3), sysid=SID, progress=meter
            )
        return jax.vmap(one)(keys)

    plain = batch(progress.NO_PROGRESS)
    plain_calls, calls[:] = len(calls), []
    fn = mpc_sampling.sampling_mpc if controller == "sampling" else mpc.receding_horizon
    compiled = fn._cache_size()
    bar = _StopAt(N + 1)  # never reached: counts only
    with progress.meter("steps", N, display=False) as meter:
        progress._BARS[int(meter.meter_id)] = bar
        counted = batch(meter)
    assert fn._cache_size() == compiled
    assert bar.seen == list(range(1, N + 1))  # one report per control step, not per episode
    np.testing.assert_array_equal(np.asarray(counted.X), np.asarray(plain.X))
    calls[:] = []
    stop = _StopAt(3)
    try:
        with progress.meter("steps", N, display=False) as meter:
            progress._BARS[int(meter.meter_id)] = stop
            stopped = batch(meter)
    finally:
        progress.clear_stop()
    assert stop.seen == [1, 2, 3]  # no report after the stop: the flag is one for the batch
    assert len(calls) == pytest.approx(plain_calls * 2 / N, rel=0.2)  # the skipped steps ran nothing
    X, U = np.asarray(stopped.X), np.asarray(stopped.U)
    np.testing.assert_array_equal(X[:, :2], np.asarray(plain.X)[:, :2])  # steps 0 and 1 ran
    np.testing.assert_array_equal(U[:, :2], np.asarray(plain.U)[:, :2])
    assert np.isnan(X[:, 2:]).all() and np.isnan(U[:, 2:]).all()  # step 2 on skipped


def test_a_long_episode_reports_about_polls_per_episode_times():
    """Every k-th control step is reported (k = steps // POLLS_PER_EPISODE): the host
    callback's cost stays bounded on episodes of cheap steps."""
    steps = 2 * POLLS_PER_EPISODE + 1
    bar = _StopAt(steps + 1)
    with progress.meter("steps", steps, display=False) as meter:
        progress._BARS[int(meter.meter_id)] = bar
        settings, spread = mpc_sampling.SamplingSettings(samples=4), mpc_sampling.hyper(0.5)
        mpc_sampling.sampling_mpc(
            _linear(),
            _task(),
            jnp.zeros((H, 1)),
            key=jax.random.key(0),
            steps=steps,
            settings=settings,
            hyper=spread,
            progress=meter,
        )
    assert bar.seen == list(range(1, steps + 1, 2))
