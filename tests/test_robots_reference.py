"""benchmarks/robots.py's reference: the best of D2C and the oracle over several starts."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from benchmarks import robots
from mjx_surrogate.control import chunked
from mjx_surrogate.control.ilqr import ILQRParams
from mjx_surrogate.identification.sysid import SysIdParams
from mjx_surrogate.runs.config import Config, SystemConfig, TaskConfig
from mjx_surrogate.runs.resolution import resolve


@pytest.mark.slow  # over 5 s: the fast tier's budget
def test_the_reference_is_the_cheapest_of_every_start_of_both_methods_and_names_it():
    res = resolve(Config(system=SystemConfig(name="pendulum", backend="native"), task=TaskConfig(T=6)))
    _, system, task = res
    params, sysid = ILQRParams(max_iter=4), SysIdParams(n_samples=4)
    U0 = jnp.zeros((task.T, 1))
    d2c = chunked.solve(system, task, U0, jax.random.key(0), params, sysid).out
    oracle = chunked.solve_exact(system, task, U0, params, jacobians="finite_difference").out
    ref = robots.best_reference(res, d2c, oracle, U0, params, sysid, 2, jax.random.key(1))
    costs = ref["costs"]
    assert [len(costs[m]) for m in ("d2c", "oracle")] == [3, 3]
    assert costs["d2c"][0] == float(d2c.cost) and costs["oracle"][0] == float(oracle.cost)
    every = [(c, m, i) for m in costs for i, c in enumerate(costs[m])]
    best, method, i = min(every)
    assert ref["cost"] == best and len(set(c for c, _, _ in every)) > 1  # the starts differ
    assert ref["from"] == f"{method}, {'the same start' if i == 0 else f'spread start {i}'}"
    assert np.isfinite(ref["cost"]) and ref["starts"] == 2
    own = ref["d2c_best"]  # D2C's best of its three starts
    assert own["cost"] == min(costs["d2c"]) and own["from"].startswith("d2c, ")
    # the goal verdicts are the goal test's on the chosen solves: at a tolerance no state
    # passes (0) both fail, at one every state passes both hold
    for tol, reached in ((0.0, False), (1e9, True)):
        again = robots.best_reference(res, d2c, oracle, U0, params, sysid, 2, jax.random.key(1), tol)
        assert again["cost"] == ref["cost"] and again["goal_reached"] is reached, (tol, again)
        assert again["d2c_best"]["goal_reached"] is reached
