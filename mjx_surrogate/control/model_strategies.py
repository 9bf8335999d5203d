"""When the iLQR loop's local model is identified: strategies as ``init``/``propose``/``update``.

A strategy (:class:`ModelStrategy`) has its own state and settings and three pure functions:

* ``init() -> state``;
* ``propose(state, proposal) -> proposal``: what to do with the model for the coming
  iteration (:class:`Proposal`: identify afresh, else carry it over by a secant update, else
  keep it; identify with the fine model), given what the strategies before it proposed;
* ``update(state, proposal, outcome, report) -> (state, report)``: its state after the step
  the loop took on the model (:class:`StepOutcome`), and what it says of that model
  (:class:`ModelReport`: may a minimum, a stall be declared on it; did the model's kind change).

:func:`chain` composes strategies in order, as optax chains transformations. The built-ins:

* :func:`every_iteration`: identify whenever the nominal moved (a rejected step keeps the model);
* :func:`secant_reuse` (``tol``, ``max_reuse``): when the accepted step's decrease was within
  ``tol`` of the model's promise, carry the model over with a secant update instead of
  identifying, at most ``max_reuse`` iterations in a row; a step rejected on a carried-over
  model is retried on an identified one; no minimum is declared on a carried-over model;
* :func:`coarse_then_fine` (``refine_tol``, ``has_fine``): identify with the coarse
  ``linearize`` until it hands over (a minimum or stall rule held on it, or a step gained at
  most ``refine_tol`` |J|), then with ``linearize_fine``; no minimum or stall on a coarse model.

The loop's default (:func:`default_strategy`) chains the three with the solver's settings,
traced, so changing them never recompiles. Strategies are registered by name
(:func:`register_model_strategy`; ``solver.model_strategy`` in a config, ``"default"`` the
chain above), each bringing its own settings (``--solver.<name>.<field>``).
"""

from __future__ import annotations

from typing import Any, Callable, NamedTuple

import jax
import jax.numpy as jnp

from mjx_surrogate.errors import registered
from mjx_surrogate.identification.sysid import SCHEMES


class Proposal(NamedTuple):
    """Identify the model afresh; else carry it over by a secant update (else keep it as it
    is); identify with ``linearize_fine`` rather than ``linearize``."""

    identify: jax.Array
    carry: jax.Array
    fine: jax.Array


class StepOutcome(NamedTuple):
    """The step the loop took on the model: a trial was accepted, its actual / predicted
    decrease, a minimum rule held, mu passed mu_max, the cost before and after the step."""

    accepted: jax.Array
    ratio: jax.Array
    at_minimum: jax.Array
    stalled: jax.Array
    cost_before: jax.Array
    cost_after: jax.Array


class ModelReport(NamedTuple):
    """What the strategies say of the model the step was taken on: a minimum may be
    declared on it (``trusted``), a stall too (``fine``); the kind of model changed
    (``handover``: the loop restarts its regularisation schedule)."""

    trusted: jax.Array
    fine: jax.Array
    handover: jax.Array


class ModelStrategy(NamedTuple):
    init: Callable[[], Any]
    propose: Callable[[Any, Proposal], Proposal]
    update: Callable[[Any, Proposal, StepOutcome, ModelReport], tuple[Any, ModelReport]]


def no_proposal() -> Proposal:
    """Keep the model (the start of :func:`chain`'s proposal)."""
    return Proposal(jnp.array(False), jnp.array(False), jnp.array(False))


def no_objection() -> ModelReport:
    """Trusted, fine, no handover (the start of :func:`chain`'s report)."""
    return ModelReport(jnp.array(True), jnp.array(True), jnp.array(False))


def chain(*strategies: ModelStrategy) -> ModelStrategy:
    """The strategies applied in order: each one's proposal and report pass to the next."""

    def init():
        return tuple(s.init() for s in strategies)

    def propose(states, proposal):
        for s, state in zip(strategies, states):
            proposal = s.propose(state, proposal)
        return proposal

    def update(states, proposal, outcome, report):
        new = []
        for s, state in zip(strategies, states):
            state, report = s.update(state, proposal, outcome, report)
            new.append(state)
        return tuple(new), report

    return ModelStrategy(init, propose, update)


class EveryIterationState(NamedTuple):
    fresh: jax.Array  # the nominal moved since the model was made


def every_iteration() -> ModelStrategy:
    """Identify whenever the nominal moved: at the start and after every accepted step."""
    return ModelStrategy(
        init=lambda: EveryIterationState(jnp.array(True)),
        propose=lambda s, p: p._replace(identify=s.fresh),
        update=lambda s, p, o, r: (EveryIterationState(o.accepted), r),
    )


class ReuseState(NamedTuple):
    """The current model was carried over rather than identified (``stale``), the last
    accepted step passed the reuse test (``ok``), iterations in a row on a carried model."""

    stale: jax.Array
    ok: jax.Array
    count: jax.Array


def secant_reuse(tol, max_reuse) -> ModelStrategy:
    """Carry the model over with a secant update after a step whose decrease was within
    ``tol`` of the promise (|actual / predicted - 1| <= tol), at most ``max_reuse``
    iterations in a row (module docstring). It acts on the proposal before it: a proposal
    to identify (the nominal moved) becomes a carry-over when the last step passed."""

    def propose(s: ReuseState, p: Proposal) -> Proposal:
        moved = p.identify
        return p._replace(identify=(moved & ~s.ok) | (~moved & s.stale), carry=moved & s.ok)

    def update(s: ReuseState, p: Proposal, o: StepOutcome, r: ModelReport):
        stale = ~p.identify & (p.carry | s.stale)
        count = jnp.where(p.identify, 0, s.count + p.carry)
        near = jnp.abs(o.ratio - 1.0) <= tol
        ok = o.accepted & near & (count < max_reuse) & ~o.at_minimum
        return ReuseState(stale, ok, count), r._replace(trusted=r.trusted & ~stale)

    return ModelStrategy(
        init=lambda: ReuseState(jnp.array(False), jnp.array(False), jnp.asarray(0)),
        propose=propose,
        update=update,
    )


class RefineState(NamedTuple):
    """Identify with ``linearize_fine`` from now on (``fine``); the current model came from
    it (``fine_model``). Both True when there is no fine model."""

    fine: jax.Array
    fine_model: jax.Array


def coarse_then_fine(refine_tol, has_fine: bool) -> ModelStrategy:
    """The coarse model until it hands over, then the fine one (module docstring);
    ``has_fine`` False: every model counts as fine."""

    def propose(s: RefineState, p: Proposal) -> Proposal:
        identify = p.identify | (s.fine & ~s.fine_model)  # a coarse model that handed over
        return p._replace(identify=identify, carry=p.carry & ~identify, fine=s.fine)

    def update(s: RefineState, p: Proposal, o: StepOutcome, r: ModelReport):
        fine_model = jnp.where(p.identify, s.fine, s.fine_model)
        gain_small = o.accepted & (o.cost_before - o.cost_after <= refine_tol * jnp.abs(o.cost_before))
        handover = ~fine_model & (o.at_minimum | o.stalled | gain_small)
        report = ModelReport(r.trusted & fine_model, r.fine & fine_model, r.handover | handover)
        return RefineState(s.fine | handover, fine_model), report

    start = jnp.array(not has_fine)
    return ModelStrategy(init=lambda: RefineState(start, start), propose=propose, update=update)


def default_strategy(params, has_fine: bool) -> ModelStrategy:
    """Every iteration, secant reuse and coarse then fine with the solver's settings
    (``ILQRParams.reuse_tol``, ``reuse_max``, ``sysid_refine_tol``); with both reuse settings 0
    and no fine model, a model is identified at every iteration."""
    return chain(
        every_iteration(),
        secant_reuse(params.reuse_tol, params.reuse_max),
        coarse_then_fine(params.sysid_refine_tol, has_fine),
    )


class StrategyKind(NamedTuple):
    """A registered model strategy: ``make(params, has_fine, settings) -> ModelStrategy``
    (``params``: the solver's ``ILQRParams``; ``has_fine``: the problem has a
    ``linearize_fine``; ``settings``: the config's values of ``settings``, the strategy's
    own defaults, a frozen dataclass, or None), and what it does, in words."""

    make: Callable[[Any, bool, Any], ModelStrategy]
    settings: Any = None
    description: str = ""


MODEL_STRATEGIES: dict[str, StrategyKind] = {}


def register_model_strategy(name: str, kind: StrategyKind) -> None:
    """Add ``kind`` under ``name`` (then valid as ``solver.model_strategy``). Its settings
    share the ``solver.<name>`` section with the identification schemes', so a name of a
    registered scheme is refused."""
    if name in SCHEMES:
        raise ValueError(f"{name!r} names an identification scheme; give the strategy another name")
    MODEL_STRATEGIES[name] = kind


def get_model_strategy(name: str, field: str = "solver.model_strategy") -> StrategyKind:
    return registered(MODEL_STRATEGIES, name, field, "model strategy")


register_model_strategy(
    "default",
    StrategyKind(
        lambda params, has_fine, settings: default_strategy(params, has_fine),
        description="identify where the nominal moved; secant reuse and coarse then fine where set",
    ),
)
