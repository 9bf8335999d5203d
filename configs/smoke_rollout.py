"""CI smoke: 32 perturbed pendulum rollouts over 10 steps."""

from mjx_surrogate.runs.config import Config, ExperimentConfig, SystemConfig, TaskConfig

CONFIG = Config(
    system=SystemConfig(name="pendulum"),
    task=TaskConfig(preset="pendulum_d2c", T=10),
    experiment=ExperimentConfig(kind="rollout", n_rollouts=32),
)
