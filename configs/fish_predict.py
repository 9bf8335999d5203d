"""Paper, Fig. Fish: surrogates of the fish around its optimal trajectory (rest -> target,
T 600) at 5 % and 30 % U_max. Sizes are reduced from the paper's 2000 trajectories to 200
(120,000 transitions): a quadratic library on the 32 inputs already has 561 columns."""

from mjx_surrogate.config import (
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
    system=SystemConfig(name="fish", timestep=0.005, substeps=5),
    task=TaskConfig(preset="fish_d2c"),
    solver=SolverConfig(  # the sample-efficient identification of fish_d2c
        sysid="forward_difference",
        sysid_design="orthogonal",
        n_samples=32,
        sysid_every=2,
        sysid_refine_tol=1e-3,
        init="random",
        init_scale=0.1,
        max_iter=300,
        rel_tol=1e-5,
        sigma_x=1e-7,
        sigma_u=1e-7,
    ),
    experiment=ExperimentConfig(kind="predict", x64=True),
    data=DataConfig(n_traj=200, levels=(0.05, 0.30)),
    surrogate=SurrogateConfig(sindy=SindyConfig(libraries=("poly2", "poly2_trig")), mlp=MLPConfig(epochs=50)),
)
