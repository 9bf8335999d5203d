"""Paper, Section "Empirical Results" (model convergence, ill-conditioning, variance) on the
cartpole swing-up: 5 data sets per level from one sampling distribution (2000 trajectories
each), SINDy at 10 % / 100 %, MLP at 5 % / 25 %; Gram spectra at 5 % (SINDy) and 5 % / 15 %
(MLP); error projections for cubic at 5 % and quartic + trig at 15 %. MLPs train up to the
paper's 5000 epochs, stopping once the best test loss fell by less than 10 % over the last
100 epochs (the convergence test; on 2 cores 5000 epochs of the 17 networks would take
about an hour)."""

from mjx_surrogate.config import (
    AnalysisConfig,
    Config,
    DataConfig,
    ExperimentConfig,
    MLPConfig,
    SindyConfig,
    SolverConfig,
    SurrogateConfig,
    SystemConfig,
    TaskConfig,
)

CONFIG = Config(
    system=SystemConfig(name="cartpole"),
    task=TaskConfig(preset="cartpole_swingup"),
    solver=SolverConfig(n_samples=25, max_iter=300, rel_tol=1e-6, init="zeros"),
    experiment=ExperimentConfig(kind="analysis", x64=True),
    data=DataConfig(n_traj=2000),
    surrogate=SurrogateConfig(
        sindy=SindyConfig(libraries=("cubic_trig", "quartic")),
        mlp=MLPConfig(epochs=5000, stop_window=100, stop_rel_tol=0.1),
    ),
    analysis=AnalysisConfig(n_datasets=5, gram_points=1000),
)
