"""D2C 2.0 cartpole: theta = pi - 0.3 -> upright at the origin, T 30, 25 samples.
The model runs at D2C 2.0's time step (timestep=0.1, substeps=1), so that times and costs compare.
"""
from mjx_surrogate.config import Config, ExperimentConfig, SolverConfig, SystemConfig, TaskConfig

CONFIG = Config(
    system=SystemConfig(name="cartpole", timestep=0.1, substeps=1),
    task=TaskConfig(preset="cartpole_d2c"),
    solver=SolverConfig(sysid="central_difference", n_samples=25, init="random", init_scale=0.1,
                        max_iter=300, rel_tol=1e-6),
    experiment=ExperimentConfig(kind="d2c"),
)
