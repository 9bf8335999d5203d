"""Paper: cartpole swing-up from 180 deg to rest at 60 deg in 30 steps, from zero controls."""

from mjx_surrogate.runs.config import (
    Config,
    ExperimentConfig,
    SolverConfig,
    SysIdConfig,
    SystemConfig,
    TaskConfig,
)

CONFIG = Config(
    system=SystemConfig(name="cartpole"),
    task=TaskConfig(preset="cartpole_swingup"),
    solver=SolverConfig(init="zeros", init_scale=0.1, max_iter=300, rel_tol=1e-6),
    sysid=SysIdConfig(scheme="central_difference", n_samples=25),
    experiment=ExperimentConfig(kind="d2c"),
)
