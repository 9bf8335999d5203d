"""The Allen-Cahn phase-field equation on 64 cells (``mjx_surrogate.systems.allen_cahn``):
D2C grows the +1 phase in the middle of a field at w = -1 in 1 s, against the jacfwd
oracle. In 2-D: ``--system.name allen_cahn2d16``; reduced-order: ``--sysid.scheme reduced``."""

from mjx_surrogate.runs.config import Config, ExperimentConfig, SystemConfig, TaskConfig

CONFIG = Config(
    system=SystemConfig(name="allen_cahn64"),
    task=TaskConfig(preset="allen_cahn_grow"),
    experiment=ExperimentConfig(kind="d2c"),
)
