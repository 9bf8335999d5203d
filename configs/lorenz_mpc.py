"""Closed loop on SINDy-MPC's Lorenz system (``mjx_surrogate.systems.lorenz``): the switch
from C- to C+ (``lorenz_switch``, 2 s) with every controller replanning over 0.5 s, under
process noise; SINDy with the system's own polynomial terms (degree 2 and 3) and an MLP,
both fitted on 100 trajectories around the offline optimum. A function black box has no
masses: the mismatch here is the noise alone."""

from mjx_surrogate.config import (
    Config,
    DataConfig,
    ExperimentConfig,
    MLPConfig,
    MPCConfig,
    SindyConfig,
    SolverConfig,
    SurrogateConfig,
    SystemConfig,
    TaskConfig,
)

CONFIG = Config(
    system=SystemConfig(name="lorenz"),
    task=TaskConfig(preset="lorenz_switch"),
    solver=SolverConfig(max_iter=300),
    experiment=ExperimentConfig(kind="mpc"),
    data=DataConfig(n_traj=100),
    surrogate=SurrogateConfig(sindy=SindyConfig(libraries=("poly2", "poly3")), mlp=MLPConfig(epochs=100)),
    mpc=MPCConfig(horizon=50, steps=200, max_iter=5, process_noise=(0.0, 0.1, 0.5), n_episodes=4),
)
