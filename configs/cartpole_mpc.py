"""Closed loop on the cartpole: hanging to upright at the origin (the paper's task,
``cartpole_upright``, with its running cost) over 4 s, every controller replanning over
2 s, on the model and on a plant 1.1x heavier, under process noise."""

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
    system=SystemConfig(name="cartpole", backend="native"),
    task=TaskConfig(preset="cartpole_upright", T=40),
    solver=SolverConfig(max_iter=300, rel_tol=1e-6),
    experiment=ExperimentConfig(kind="mpc", x64=True),
    data=DataConfig(n_traj=200),
    surrogate=SurrogateConfig(sindy=SindyConfig(libraries=("cubic_trig",)), mlp=MLPConfig(epochs=200)),
    mpc=MPCConfig(
        horizon=20,
        steps=40,
        max_iter=5,
        process_noise=(0.0, 0.01),
        plant_mass_scales=(1.0, 1.1),
        n_episodes=2,
    ),
)
