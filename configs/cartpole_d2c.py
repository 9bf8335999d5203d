"""D2C 2.0 cartpole: theta = pi - 0.3 -> upright at the origin, T 30, 25 samples.
The model runs at D2C 2.0's time step (timestep=0.1, substeps=1), so that times and costs compare.
Forward differences (26 instead of 50 simulations per time step) reach the exact oracle's
cost here in float32 (docs/performance.md); "central_difference" is D2C 2.0's LLS-CD.
"""

from mjx_surrogate.config import Config, ExperimentConfig, SolverConfig, SystemConfig, TaskConfig

CONFIG = Config(
    system=SystemConfig(name="cartpole", timestep=0.1, substeps=1),
    task=TaskConfig(preset="cartpole_d2c"),
    solver=SolverConfig(
        sysid="forward_difference", n_samples=25, init="random", init_scale=0.1, max_iter=300, rel_tol=1e-6
    ),
    experiment=ExperimentConfig(kind="d2c"),
)
