"""The viscous Burgers equation on 64 cells (``mjx_surrogate.systems.burgers``): D2C damps
the steepening wave sin(2 pi xi) to rest in 0.5 s, against the jacfwd oracle. For a finer
grid and the reduced-order scheme: ``--system.name burgers1024 --sysid.scheme reduced``."""

from mjx_surrogate.runs.config import Config, ExperimentConfig, SystemConfig, TaskConfig

CONFIG = Config(
    system=SystemConfig(name="burgers64"),
    task=TaskConfig(preset="burgers_damp"),
    experiment=ExperimentConfig(kind="d2c"),
)
