"""How a sampling planner draws its candidate plans and updates its distribution: one
:class:`SamplingRule` per algorithm, as hydrax's planners share one base and differ in
these two steps (:mod:`mjx_surrogate.control.mpc_sampling` runs them).

A plan is a spline's knots; the distribution over them a mean mu [k, nu] and a spread
sigma [k, nu] (control units). With z ~ N(0, I):

- predictive sampling (Howell et al. 2022): the mean itself and S - 1 draws mu + sigma z;
  the mean moves to the cheapest;
- MPPI ("MPPI-generic", hydrax's): S draws mu + sigma z; the mean moves to their average
  weighted by softmax(-J / lambda);
- CEM: S - E' draws mu + sigma z and E' (``explore``) at the starting spread; the mean and
  spread move to the E cheapest ("elites") draws' mean and standard deviation, the spread
  kept at least sigma_min.

Registering a rule (:func:`register_rule`) makes it a planner's ``rule``.
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import jax
import jax.numpy as jnp

from mjx_surrogate.errors import registered


class SamplingHyper(NamedTuple):
    """A sampling planner's traced numbers: the starting spread ``sigma`` (scalar or [nu],
    control units), MPPI's ``temperature`` (cost units) and CEM's spread floor
    ``sigma_min`` (scalar or [nu], control units)."""

    sigma: jax.Array
    temperature: jax.Array
    sigma_min: jax.Array


class SamplingRule(NamedTuple):
    """``sample(key, mean, spread, n, explore, hyper) -> knots [n, k, nu]`` (clipped to the
    limits by the caller); ``update(knots [n, k, nu], costs [n], mean, spread, elites,
    hyper) -> (mean, spread)``."""

    sample: Callable
    update: Callable
    description: str = ""


def _draws(key, mean, spread, n):
    return mean + spread * jax.random.normal(key, (n,) + mean.shape, mean.dtype)


def _ps_sample(key, mean, spread, n, explore, hyper):
    return jnp.concatenate([mean[None], _draws(key, mean, spread, n - 1)])


def _ps_update(knots, costs, mean, spread, elites, hyper):
    return knots[jnp.argmin(costs)], spread


def _mppi_sample(key, mean, spread, n, explore, hyper):
    return _draws(key, mean, spread, n)


def _mppi_update(knots, costs, mean, spread, elites, hyper):
    w = jax.nn.softmax(-costs / hyper.temperature)
    return jnp.einsum("s,skj->kj", w, knots), spread


def _cem_sample(key, mean, spread, n, explore, hyper):
    k_main, k_explore = jax.random.split(key)
    start = jnp.broadcast_to(hyper.sigma, mean.shape).astype(mean.dtype)
    main = _draws(k_main, mean, spread, n - explore)
    return jnp.concatenate([main, _draws(k_explore, mean, start, explore)])


def _cem_update(knots, costs, mean, spread, elites, hyper):
    best = knots[jnp.argsort(costs)[:elites]]
    return best.mean(axis=0), jnp.maximum(best.std(axis=0), hyper.sigma_min)


RULES: dict[str, SamplingRule] = {
    "predictive_sampling": SamplingRule(_ps_sample, _ps_update, "the cheapest of the mean and S - 1 draws"),
    "mppi": SamplingRule(_mppi_sample, _mppi_update, "the draws' softmax(-J / temperature)-weighted mean"),
    "cem": SamplingRule(_cem_sample, _cem_update, "the elites' mean and spread (cross-entropy method)"),
}


def register_rule(name: str, rule: SamplingRule) -> None:
    """Add ``rule`` under ``name``."""
    RULES[name] = rule


def get_rule(name: str, field: str = "rule") -> SamplingRule:
    return registered(RULES, name, field, "sampling rule")
