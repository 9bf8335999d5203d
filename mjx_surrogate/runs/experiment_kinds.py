"""The experiment kinds a run can be (``experiment.kind``): a registry of declarations.

A kind is one module with ``run(resolved, record, key) -> status`` plus one entry here
saying what it needs checked before anything compiles and what it adds to the run
folder. ``run`` is a callable, or a ``"module:function"`` target imported when the run
starts (how the built-in kinds, in ``experiments/``, are declared without this package
importing them). A kind may bring its own settings (``settings``: a frozen dataclass of
defaults, set as ``--experiment.<kind>.<field>``, :mod:`mjx_surrogate.runs.extension_settings`).
"""

from __future__ import annotations

import dataclasses
import importlib
from typing import Any, Callable, NamedTuple, Union

from mjx_surrogate.errors import ConfigError, registered
from mjx_surrogate.surrogates.registry import get_surrogate, library_specs

# what resolve() checks for a kind before any compile
IDENTIFICATION = "identification"  # sysid.n_samples against nx + nu, the memory of a batch
SURROGATES = "surrogates"  # section surrogate and the data split
LTV_BASELINE = "ltv_baseline"  # enough training trajectories for the per-step LTV fit
NEEDS = (IDENTIFICATION, SURROGATES, LTV_BASELINE)


class ExperimentKind(NamedTuple):
    """run: ``run(resolved, record, key) -> status`` or its ``"module:function"``.
    needs: a subset of :data:`NEEDS`, or a function of the config giving one.
    validate(config, system): further checks of the kind's own, raising ConfigError
    (after the needs, before any compile). writes: what
    the kind adds to the run folder, in words. settings: the kind's own settings' defaults
    (a frozen dataclass instance) or None."""

    run: Union[Callable[..., str], str]
    needs: Union[frozenset, Callable[[Any], frozenset]] = frozenset()
    validate: Callable[[Any, Any], None] = lambda config, system: None
    writes: str = ""
    description: str = ""
    settings: Any = None


EXPERIMENTS: dict[str, ExperimentKind] = {}


def register_experiment(name: str, kind: ExperimentKind) -> None:
    """Add ``kind`` under ``name`` (then valid as ``experiment.kind``)."""
    unknown = set() if callable(kind.needs) else set(kind.needs) - set(NEEDS)
    if unknown:
        raise ValueError(f"experiment kind {name!r} needs {sorted(unknown)}; valid: {', '.join(NEEDS)}")
    EXPERIMENTS[name] = kind


def get_experiment(name: str, field: str = "experiment.kind") -> ExperimentKind:
    return registered(EXPERIMENTS, name, field, "experiment kind")


def needs_of(config) -> frozenset:
    """What the config's kind needs checked (:data:`NEEDS`)."""
    needs = get_experiment(config.experiment.kind).needs
    return frozenset(needs(config) if callable(needs) else needs)


def runner(name: str) -> Callable[..., str]:
    """The run function of kind ``name``, its module imported if it is a target string."""
    target = get_experiment(name).run
    if callable(target):
        return target
    module, _, attr = target.partition(":")
    return getattr(importlib.import_module(module), attr)


def _check_horizon(config, system) -> None:
    if config.data.n_traj < system.nx + system.nu:
        raise ConfigError(
            "data.n_traj",
            f"must be >= nx + nu = {system.nx + system.nu} for the per-step least squares, "
            f"got {config.data.n_traj}",
        )


def analysis_library_specs(cfg, system) -> dict:
    """The libraries the analysis section names, each checked under its own field."""
    a = cfg.analysis
    out = library_specs(cfg, system, a.convergence_library, "analysis.convergence_library")
    out |= library_specs(cfg, system, a.gram_libraries, "analysis.gram_libraries")
    return out | library_specs(cfg, system, a.variance_libraries, "analysis.variance_libraries")


def training_transitions(cfg) -> int:
    """Transitions in the training split of section data (``cfg.task.T`` resolved)."""
    d = cfg.data
    return (d.n_traj - max(1, int(round(d.test_fraction * d.n_traj)))) * int(cfg.task.T)


def _check_analysis(config, system) -> None:
    """The analyses fit SINDy and MLPs whatever ``surrogate.kinds`` says."""
    analysis_library_specs(config, system)
    get_surrogate("mlp").validate(config, system, training_transitions(config))
    if config.surrogate.mlp.patience > 0:
        raise ConfigError(
            "surrogate.mlp.patience",
            "the analyses' networks stop by the convergence test (surrogate.mlp.stop_window); set 0",
        )


def _mpc_needs(config) -> frozenset:
    surrogates = {SURROGATES} if "surrogates" in config.mpc.controllers else set()
    return frozenset({IDENTIFICATION} | surrogates)


@dataclasses.dataclass(frozen=True)
class ControlSettings:
    """The control study's own settings (``--experiment.control.<field>``).

    starts: D2C and the exact oracle (where ``experiment.exact_oracle`` is on) also from
    this many random starts of ``solver.init`` (drawn from the experiment's seed, solved
    along a leading axis), each D2C solve judged against the oracle's from the same start:
    the claim "the LTV approach reaches the optimum from a random start" over several
    draws; 0: only the run's own start."""

    starts: int = 0

    def check(self) -> None:
        if self.starts < 0 or self.starts == 1:
            raise ConfigError("starts", f"must be 0 (off) or at least 2, got {self.starts}")


_FIT = frozenset({IDENTIFICATION, SURROGATES, LTV_BASELINE})
for _name, _kind in {
    "rollout": ExperimentKind(
        "experiments.rollout_study:run",
        writes="perturbed rollouts around the zero-control nominal and their spread",
        description="n_rollouts perturbed rollouts (rollout_sigma_x, rollout_sigma_u)",
    ),
    "d2c": ExperimentKind(
        "experiments.d2c_study:run",
        frozenset({IDENTIFICATION}),
        writes="the D2C optimum (d2c_X, d2c_U, gains), the oracle's, feedback under noise",
        description="data-driven iLQR against the exact-Jacobian oracle, then feedback under noise",
    ),
    "predict": ExperimentKind(
        "experiments.predict_study:run",
        _FIT,
        writes="per level: each surrogate's and the LTV model's prediction errors",
        description="data around the optimum, SINDy / MLP / LTV predictions (the paper's section 5)",
    ),
    "analysis": ExperimentKind(
        "experiments.analysis_study:run",
        _FIT,
        _check_analysis,
        writes="convergence across seeds, Gram conditioning, variance",
        description="why the global fits fail: the paper's analysis section",
    ),
    "theory": ExperimentKind(
        "experiments.theory_study:run",
        writes="exact moments against Monte Carlo",
        description="the paper's formulas checked against sampling",
    ),
    "control": ExperimentKind(
        "experiments.control_study:run",
        _FIT,
        writes="iLQR on each surrogate, its controls judged on the black box; D2C and the "
        "oracle from experiment.control.starts random starts",
        description="surrogate-based control against D2C and the oracle",
        settings=ControlSettings(),
    ),
    "horizon": ExperimentKind(
        "experiments.horizon_study:run",
        frozenset({IDENTIFICATION}),
        _check_horizon,
        writes="identification error against the rollout length, open and closed loop",
        description="the LTV fit's error against the rollout length",
    ),
    "mpc": ExperimentKind(
        "experiments.mpc_study:run",
        _mpc_needs,
        writes="per controller and condition: closed-loop episodes, costs, effort",
        description="receding-horizon control on the black box, controllers side by side",
    ),
}.items():
    register_experiment(_name, _kind)
