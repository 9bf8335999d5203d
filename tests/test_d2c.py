"""D2C against the exact oracle from the same start; multi-start; feedback; no recompile."""

import glob
import json
import os

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import assert_png

from experiments import run as cli
from mjx_surrogate.analysis.evaluation import evaluate_feedback
from mjx_surrogate.control.d2c import solve_d2c, solve_exact, solve_multistart
from mjx_surrogate.control.ilqr import ILQRParams
from mjx_surrogate.identification.rollout import rollout
from mjx_surrogate.identification.sysid import SysIdParams
from mjx_surrogate.runs.config import Config, SystemConfig, TaskConfig
from mjx_surrogate.runs.pipeline import initial_controls
from mjx_surrogate.runs.resolution import resolve
from mjx_surrogate.tasks import trajectory_cost


def problem(name, preset, backend, **task):
    res = resolve(
        Config(system=SystemConfig(name=name, backend=backend), task=TaskConfig(preset=preset, **task))
    )
    return res.system, res.task


# One set of settings for the pendulum's jacfwd oracle: its program is compiled once
PENDULUM_ORACLE = ILQRParams(max_iter=100, rel_tol=1e-7)


@pytest.mark.parametrize(
    "sid",
    [SysIdParams(n_samples=10), SysIdParams(1e-6, 1e-6, "forward_difference", 10)],
    ids=["central", "forward"],
)
@pytest.mark.slow
def test_pendulum_d2c_matches_exact_oracle(sid):
    s, task = problem("pendulum", "pendulum_d2c", "mjx")
    U0 = initial_controls(jax.random.key(0), task.T, 1, "random", 0.1)
    p = PENDULUM_ORACLE
    d2c = solve_d2c(s, task, U0, jax.random.key(1), p, sid)
    ex = solve_exact(s, task, U0, p)
    assert bool(d2c.converged) and bool(ex.converged)
    assert float(d2c.cost) == pytest.approx(float(ex.cost), rel=1e-4)
    # the cost the solver reports is the cost of its controls on the black box
    X = rollout(s, task.x0[None], d2c.U[None])[0]
    assert float(trajectory_cost(task, X, d2c.U)) == pytest.approx(float(d2c.cost), rel=1e-9)
    # no recompilation for new values of the same shapes
    n = solve_d2c._cache_size()
    solve_d2c(s, task, U0 + 0.01, jax.random.key(5), p, sid.replace(sigma_x=2e-6))
    assert solve_d2c._cache_size() == n


@pytest.mark.slow
def test_cartpole_d2c_on_native_black_box_matches_finite_difference_oracle():
    # The jacfwd oracle is checked on the pendulum above; on the cartpole it compiles for
    # about 67 s (docs/performance.md), so the coordinate finite-difference oracle stands in.
    s, task = problem("cartpole", "cartpole_d2c", "native")
    U0 = jnp.zeros((task.T, 1))
    p = ILQRParams(max_iter=300, rel_tol=1e-6)
    d2c = solve_d2c(s, task, U0, jax.random.key(1), p, SysIdParams(n_samples=10))
    ex = solve_exact(s, task, U0, p, jacobians="finite_difference")
    assert bool(d2c.converged) and bool(ex.converged)
    assert float(d2c.cost) == pytest.approx(float(ex.cost), rel=1e-2)
    h = np.asarray(d2c.cost_history)[: int(d2c.iterations) + 1]
    assert np.all(np.isfinite(h)) and np.all(np.diff(h) <= 0)  # monotone, no blown-up trial


@pytest.mark.slow
def test_multistart_keeps_the_best_and_limits_hold():
    # backend-agnostic: the native pendulum's solve compiles in about a fifth of MJX's
    s, task = problem("pendulum", "pendulum_d2c", "native", u_min=(-3.0,), u_max=(3.0,))
    U0s = initial_controls(jax.random.key(2), task.T, 1, "random", 1.0, n=3)
    ms = solve_multistart(s, task, U0s, jax.random.key(3), ILQRParams(max_iter=60), SysIdParams(n_samples=10))
    costs = np.asarray(ms.costs)
    assert costs.shape == (3,)
    assert float(ms.best.cost) == pytest.approx(costs.min())
    assert np.all(np.abs(np.asarray(ms.best.U)) <= 3.0 + 1e-12)


@pytest.mark.slow
def test_feedback_without_noise_reproduces_the_nominal():
    s, task = problem("pendulum", "pendulum_d2c", "mjx")
    res = solve_exact(s, task, jnp.zeros((task.T, 1)), PENDULUM_ORACLE)
    closed, opened = evaluate_feedback(
        s, task, res.X, res.U, res.K, jnp.array([0.0, 0.1]), jax.random.key(0), 16
    )
    assert np.allclose(closed[0], float(res.cost), rtol=1e-9)
    assert np.allclose(opened[0], float(res.cost), rtol=1e-9)
    assert np.median(closed[1]) < np.median(opened[1])  # the local feedback helps
    # The stored nominal is not trusted: the feedback acts around the nominal re-simulated
    # in the same program, so a nominal off by round-off (here 1e-3, exaggerated) cannot
    # turn into a feedback kick (on an unstable optimum that gave 2.8e9 against 6270).
    closed, opened = evaluate_feedback(
        s, task, res.X + 1e-3, res.U, 100 * res.K, jnp.zeros(2), jax.random.key(0), 16
    )
    assert np.allclose(closed, float(res.cost), rtol=1e-9) and np.allclose(opened, float(res.cost), rtol=1e-9)


@pytest.mark.slow
def test_d2c_experiment_writes_schema(tmp_path):
    code = cli.main(["smoke_d2c", "--out", str(tmp_path)])
    assert code == 0
    (path,) = glob.glob(str(tmp_path / "*smoke_d2c"))
    m = json.load(open(os.path.join(path, "metrics.json")))
    a = np.load(os.path.join(path, "arrays.npz"))
    for name in ("d2c", "exact"):
        assert {"cost", "iterations", "converged", "compile_s", "run_s"} <= set(m[name])
        assert a[f"{name}_U"].shape == (10, 1) and a[f"{name}_X"].shape == (11, 2)
    assert a["d2c_U0"].shape == (10, 1)
    assert m["ltv_relative_error"]["median"] < 1e-2
    assert m["status"] == "converged" and m["d2c"]["status"] == "converged"
    assert {"d2c", "exact", "ltv_relative_error", "feedback"} <= set(m["stages"])
    assert all(st["status"] == "done" for st in m["stages"].values())
    assert 0 < m["d2c"]["simulations_to_optimum"]["1%"] <= m["d2c"]["simulations_to_optimum"]["0.1%"]
    assert m["d2c"]["simulations_to_optimum"]["0.1%"] <= m["d2c"]["simulated_steps"]
    assert abs(m["d2c"]["replay_gap"]) < 1e-2 and m["d2c"]["native_float64"]["judged_by"] == "closed_loop"
    names = "cost_history trajectory_evolution feedback_noise cost_vs_simulations".split()
    for f in (n + ".png" for n in names):
        assert_png(os.path.join(path, f))


def test_ltv_error_leaves_out_a0_where_the_start_is_given():
    """With x_0 given (a one-step scheme, perturb_x0 off) A_0 is 0 by design and unused:
    the reported LTV error at t = 0 is that of B_0 alone, not 100 % for the A_0 the solver
    never needed. With x_0 perturbed, A_0 is identified and compared."""
    from experiments.d2c_study import ltv_error

    s, task = problem("pendulum", "pendulum_d2c", "native", T=6)
    U = 0.3 * jax.random.normal(jax.random.key(2), (task.T, s.nu), task.x0.dtype)
    X = rollout(s, task.x0, U)
    K = jnp.zeros((task.T, s.nu, s.nx))
    for perturb_x0 in (False, True):
        p = SysIdParams(sigma_x=1e-6, sigma_u=1e-6, n_samples=20, perturb_x0=perturb_x0)
        err = ltv_error(s, X, U, K, jax.random.key(3), p, "finite_difference")
        assert err["max"] < 1e-6, (perturb_x0, err)


def test_an_unknown_method_or_oracle_is_refused_not_solved_as_the_exact_oracle():
    from mjx_surrogate.control import d2c

    _, system, task = resolve(
        Config(system=SystemConfig(name="pendulum"), task=TaskConfig(preset="pendulum_d2c"))
    )
    with pytest.raises(ValueError, match="'exact': valid: d2c, jacfwd, finite_difference"):
        d2c.problem(system, task, SysIdParams(), "exact")  # one vocabulary: the oracles' own names
    for refused in (lambda: d2c.check_oracle("jacrev"), lambda: d2c.exact_linearize(system, "jacrev")):
        with pytest.raises(ValueError, match="'jacrev': valid: jacfwd, finite_difference"):
            refused()
    assert d2c.problem(system, task, SysIdParams(), "jacfwd").trial_rollouts is None  # the names still work
    assert d2c.check_oracle("finite_difference") == "finite_difference"
