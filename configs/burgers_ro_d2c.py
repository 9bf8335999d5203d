"""Reduced-order D2C (RO-D2C) on the viscous Burgers equation on 1024 cells: the
``burgers_damp`` task, 32 snapshot rollouts per identification, against the jacfwd oracle
(docs/pde.md). About 90 s on 2 cores, most of it the oracle's full-order backward pass."""

from mjx_surrogate.runs.config import Config, ExperimentConfig, SysIdConfig, SystemConfig, TaskConfig

CONFIG = Config(
    system=SystemConfig(name="burgers1024"),
    task=TaskConfig(preset="burgers_damp"),
    sysid=SysIdConfig(scheme="reduced"),
    experiment=ExperimentConfig(kind="d2c"),
)
