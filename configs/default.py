"""The embedded default: D2C swing-up of the pendulum against the exact oracle (~1 min).

The solver runs on SolverConfig's own defaults, so that this preset and
``Config(system=SystemConfig(name="pendulum"), task=TaskConfig(preset="pendulum_d2c"))``
from Python are the same run."""

from mjx_surrogate.runs.config import Config, ExperimentConfig, SystemConfig, TaskConfig

CONFIG = Config(
    system=SystemConfig(name="pendulum"),
    task=TaskConfig(preset="pendulum_d2c"),
    experiment=ExperimentConfig(kind="d2c"),
)
