"""CI smoke: the theory experiment, orders 1..4, small Monte Carlo."""

from mjx_surrogate.runs.config import AnalysisConfig, Config, ExperimentConfig

CONFIG = Config(
    experiment=ExperimentConfig(kind="theory", x64=True, progress=False),
    analysis=AnalysisConfig(
        theory_max_order=4, theory_sigmas=(1.0,), theory_mc_samples=200, theory_mc_trials=50
    ),
)
