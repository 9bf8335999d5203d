"""Paper, Section "Data Driven Solutions": variance of the Gram entries and conditioning for
monomial (Gaussian), Hermite (Gaussian) and Legendre (uniform) bases, orders 1..10:
exact rational moments, Monte Carlo, and the paper's printed formulas."""

from mjx_surrogate.runs.config import AnalysisConfig, Config, ExperimentConfig

CONFIG = Config(
    experiment=ExperimentConfig(kind="theory", x64=True),
    analysis=AnalysisConfig(
        theory_max_order=10, theory_sigmas=(0.5, 1.0), theory_mc_samples=2000, theory_mc_trials=400
    ),
)
