"""The sections of the data-driven studies: ``data`` (the perturbed data sets),
``surrogate`` (SINDy, MLP and POD-SINDy fits) and ``analysis`` (the analysis and theory
studies)."""

from __future__ import annotations

import dataclasses
import math
from typing import Literal, Optional, Tuple

from mjx_surrogate.errors import ConfigError
from mjx_surrogate.runs.config.checks import at_least, check_finite, nonnegative


@dataclasses.dataclass(frozen=True)
class DataConfig:
    """Data sets sampled around the task's optimum (mjx_surrogate.identification.data).

    levels: control perturbation std as fractions of U_max (largest |u*| per channel).
    n_traj trajectories of the task's horizon per level; split train : test by
    test_fraction (paper: 2000 trajectories, 9 : 1). n_seeds data sets per level.
    """

    n_traj: int = 2000
    levels: Tuple[float, ...] = (0.05, 0.10, 0.15, 0.25, 0.30, 0.60, 1.00)
    x0_sigma: float = 0.0
    test_fraction: float = 0.1
    n_seeds: int = 1

    def check(self) -> None:
        """Refuses bad values (ConfigError naming the field)."""
        at_least(1, {"data.n_traj": self.n_traj, "data.n_seeds": self.n_seeds})
        check_finite("data.levels", self.levels)
        if not self.levels or any(v <= 0 for v in self.levels):
            bad = ", ".join(f"{v:g}" for v in self.levels if v <= 0) or "none"
            raise ConfigError("data.levels", f"give one or more levels > 0 (fractions of U_max), got {bad}")
        if not 0 < self.test_fraction < 1:
            raise ConfigError("data.test_fraction", f"must be in (0, 1), got {self.test_fraction}")
        if self.n_traj < 2:
            raise ConfigError("data.n_traj", f"needs >= 2 trajectories to split, got {self.n_traj}")
        nonnegative({"data.x0_sigma": self.x0_sigma})


@dataclasses.dataclass(frozen=True)
class SindyConfig:
    """SINDy-style least squares (surrogate kind "sindy").

    libraries: names "poly<d>" with optional suffixes "_nocross", "_trig", "_prod"
    (aliases: cubic_trig = poly3_trig, quartic = poly4, quartic_trig = poly4_trig).
    trig_coords: indices into z = [x, u] for sin/cos terms (None: the hinge angles).
    stlsq_threshold > 0 fits by STLSQ (columns normalised), else plain least squares.
    """

    libraries: Tuple[str, ...] = ("cubic_trig", "quartic", "quartic_trig")
    trig_coords: Optional[Tuple[int, ...]] = None
    harmonics: int = 1
    stlsq_threshold: float = 0.0
    stlsq_alpha: float = 0.05
    method: Literal["svd", "normal"] = "svd"

    def check(self) -> None:
        """Refuses bad values (ConfigError naming the field)."""
        at_least(1, {"surrogate.sindy.harmonics": self.harmonics})
        nonnegative(
            {
                "surrogate.sindy.stlsq_threshold": self.stlsq_threshold,
                "surrogate.sindy.stlsq_alpha": self.stlsq_alpha,
            }
        )


@dataclasses.dataclass(frozen=True)
class MLPConfig:
    """Flax MLPs (surrogate kind "mlp"); the paper's by default: 32 -> ReLU -> 64 -> ReLU,
    Adam 1e-4, weight decay 1e-6, minibatches of 256. checkpoints: epochs whose
    parameters are kept (analysis). epochs: the most epochs; with stop_window > 0 training
    stops earlier once the best held-out loss fell by less than stop_rel_tol (relative) over
    the last stop_window epochs (the convergence test). patience > 0: early stopping on a
    validation set of whole trajectories (validation_fraction of the training ones): stop
    once its loss has not improved for patience epochs and keep the best epoch's network.
    fixed_epochs_beside N > 0: also fit the paper's network (all training data, exactly N
    epochs, the same initialisation), labelled "MLP N epochs"."""

    widths: Tuple[int, ...] = (32, 64)
    learning_rate: float = 1e-4
    weight_decay: float = 1e-6
    batch_size: int = 256
    epochs: int = 200
    checkpoints: Tuple[int, ...] = ()
    stop_window: int = 0
    stop_rel_tol: float = 0.0
    patience: int = 0
    validation_fraction: float = 0.1
    fixed_epochs_beside: int = 0

    def check(self) -> None:
        """Refuses bad values (ConfigError naming the field)."""
        at_least(1, {"surrogate.mlp.batch_size": self.batch_size, "surrogate.mlp.epochs": self.epochs})
        nonnegative({"surrogate.mlp.weight_decay": self.weight_decay})
        if self.stop_window < 0:
            raise ConfigError(
                "surrogate.mlp.stop_window", f"must be >= 0 (0: no stopping test), got {self.stop_window}"
            )
        if not (math.isfinite(self.stop_rel_tol) and 0 <= self.stop_rel_tol < 1):
            raise ConfigError("surrogate.mlp.stop_rel_tol", f"must be in [0, 1), got {self.stop_rel_tol}")
        for field, v in {"patience": self.patience, "fixed_epochs_beside": self.fixed_epochs_beside}.items():
            if v < 0:
                raise ConfigError(f"surrogate.mlp.{field}", f"must be >= 0 (0: off), got {v}")
        if not (math.isfinite(self.validation_fraction) and 0 < self.validation_fraction < 1):
            raise ConfigError(
                "surrogate.mlp.validation_fraction", f"must be in (0, 1), got {self.validation_fraction}"
            )
        if not (math.isfinite(self.learning_rate) and self.learning_rate > 0):
            raise ConfigError("surrogate.mlp.learning_rate", f"must be > 0, got {self.learning_rate}")
        if not self.widths or any(w < 1 for w in self.widths):
            raise ConfigError("surrogate.mlp.widths", f"needs positive layer widths, got {self.widths}")
        bad = [e for e in self.checkpoints if not 0 <= e <= self.epochs]
        if bad:
            raise ConfigError("surrogate.mlp.checkpoints", f"{bad} outside 0..mlp.epochs={self.epochs}")


@dataclasses.dataclass(frozen=True)
class PodSindyConfig:
    """SINDy on POD coefficients (surrogate kind "pod_sindy", for black boxes with many
    states such as PDEs): the leading ``rank`` POD modes of the training states, one model
    per library name (as surrogate.sindy.libraries; no trig terms) on [modes, u]."""

    rank: int = 8
    libraries: Tuple[str, ...] = ("poly1", "poly2")


@dataclasses.dataclass(frozen=True)
class SurrogateConfig:
    """Global surrogates fitted on the data sets (``mjx_surrogate.surrogates``).

    kinds: registered surrogate kinds to fit, in order (built in: "sindy", "mlp",
      "pod_sindy").
    increment: models predict x_{t+1} - x_t instead of x_{t+1}.
    reduced_ltv_tol: the prediction study also fits the local LTV model in the data's own
      snapshot basis per t (energy rule as sysid.rank_tol), "LTV reduced": for black
      boxes with many states, whose data around the optimum span few directions per t
      (docs/pde.md); None: not fitted.
    One nested section per built-in kind.
    """

    kinds: Tuple[str, ...] = ("sindy", "mlp")
    increment: bool = False
    reduced_ltv_tol: Optional[float] = None
    sindy: SindyConfig = SindyConfig()
    mlp: MLPConfig = MLPConfig()
    pod_sindy: PodSindyConfig = PodSindyConfig()

    def check(self) -> None:
        """Refuses bad values (ConfigError naming the field); the kinds' names are checked
        against their registry by :func:`mjx_surrogate.runs.validation.validate_static`."""
        self.sindy.check()
        self.mlp.check()
        tol = self.reduced_ltv_tol
        if tol is not None and not (math.isfinite(tol) and 0 <= tol < 1):
            raise ConfigError("surrogate.reduced_ltv_tol", f"must be in [0, 1) (or unset), got {tol}")


@dataclasses.dataclass(frozen=True)
class AnalysisConfig:
    """The paper's analyses (kinds "analysis" and "theory").

    n_datasets: data sets drawn with different seeds from one sampling distribution.
    convergence_sindy_levels / convergence_mlp_levels: levels of the model-convergence
    figures (paper: SINDy 10 % and 100 %, MLP 5 % and 25 %), with convergence_library.
    gram_sindy_level, gram_libraries: the Gram-matrix spectra (paper: 5 %, cubic + trig
    and quartic). gram_mlp_levels: the MLP parameter-Jacobian Gram (paper: 5 %, 15 %) on
    gram_points transitions. variance_libraries / variance_levels (paired): projections
    of the error on the basis across data sets (paper: cubic at 5 %, quartic + trig at 15 %).
    theory_*: orders 1..theory_max_order, Gaussian scales, Monte Carlo size.
    """

    n_datasets: int = 5
    convergence_library: str = "cubic_trig"
    convergence_sindy_levels: Tuple[float, ...] = (0.10, 1.00)
    convergence_mlp_levels: Tuple[float, ...] = (0.05, 0.25)
    gram_sindy_level: float = 0.05
    gram_libraries: Tuple[str, ...] = ("cubic_trig", "quartic")
    gram_mlp_levels: Tuple[float, ...] = (0.05, 0.15)
    gram_points: int = 1000
    variance_libraries: Tuple[str, ...] = ("cubic", "quartic_trig")
    variance_levels: Tuple[float, ...] = (0.05, 0.15)
    theory_max_order: int = 10
    theory_sigmas: Tuple[float, ...] = (0.5, 1.0)
    theory_mc_samples: int = 1000
    theory_mc_trials: int = 400

    def check(self) -> None:
        """Refuses bad values (ConfigError naming the field)."""
        for field, v in {
            "analysis.n_datasets": self.n_datasets - 1,
            "analysis.gram_points": self.gram_points,
            "analysis.theory_max_order": self.theory_max_order,
            "analysis.theory_mc_samples": self.theory_mc_samples - 1,
            "analysis.theory_mc_trials": self.theory_mc_trials - 1,
        }.items():
            if v < 1:
                raise ConfigError(field, "too small (n_datasets, theory_mc_* >= 2; others >= 1)")
        if len(self.variance_libraries) != len(self.variance_levels):
            raise ConfigError("analysis.variance_levels", "needs one level per variance library")
        for field, vals in {
            "analysis.convergence_sindy_levels": self.convergence_sindy_levels,
            "analysis.convergence_mlp_levels": self.convergence_mlp_levels,
            "analysis.gram_mlp_levels": self.gram_mlp_levels,
            "analysis.variance_levels": self.variance_levels,
            "analysis.theory_sigmas": self.theory_sigmas,
            "analysis.gram_sindy_level": (self.gram_sindy_level,),
        }.items():
            check_finite(field, vals)
            if any(v <= 0 for v in vals):
                raise ConfigError(field, "levels and scales must be > 0")
        if self.theory_max_order > 14:
            raise ConfigError("analysis.theory_max_order", "at most 14 (exact rational arithmetic)")
