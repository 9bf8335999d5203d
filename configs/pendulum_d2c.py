"""D2C 2.0 pendulum: theta = pi - 0.1 -> upright, T 30, 10 samples per identification.
The model runs at D2C 2.0's time step (timestep=0.1, substeps=1), so that times and costs compare.
"""

from mjx_surrogate.runs.config import (
    Config,
    ExperimentConfig,
    SolverConfig,
    SysIdConfig,
    SystemConfig,
    TaskConfig,
)

CONFIG = Config(
    system=SystemConfig(name="pendulum", timestep=0.1, substeps=1),
    task=TaskConfig(preset="pendulum_d2c"),
    solver=SolverConfig(init="random", init_scale=0.1, max_iter=100, rel_tol=1e-6),
    sysid=SysIdConfig(scheme="central_difference", n_samples=10),
    experiment=ExperimentConfig(kind="d2c"),
)
