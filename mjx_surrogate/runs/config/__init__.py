"""Frozen dataclass configs, one module per section, each section's ``check`` beside its
fields: ``system`` (:mod:`.system`), ``task`` (:mod:`.task`), ``solver`` and ``sysid``
(:mod:`.solver`), ``mpc`` (:mod:`.mpc`), ``data``, ``surrogate`` and ``analysis``
(:mod:`.learning`), ``experiment`` and ``parallel`` (:mod:`.experiment`); the whole
:class:`Config` and its dict form in :mod:`.schema`.

A config is plain data. :func:`mjx_surrogate.runs.validation.validate_static` checks it
(every section's ``check``, then the names of registered extensions) and ``resolve`` (in
:mod:`mjx_surrogate.runs.resolution`) turns it into a system, a task and a fully resolved
config; every check raises :class:`~mjx_surrogate.errors.ConfigError` naming the field,
before any XLA compile.
"""

from mjx_surrogate.runs.config.checks import check_finite
from mjx_surrogate.runs.config.experiment import ExperimentConfig, ParallelConfig
from mjx_surrogate.runs.config.goal import PointGoal
from mjx_surrogate.runs.config.learning import (
    AnalysisConfig,
    DataConfig,
    MLPConfig,
    PodSindyConfig,
    SindyConfig,
    SurrogateConfig,
)
from mjx_surrogate.runs.config.mpc import MPC_CONTROLLERS, MPCConfig, MPCSysIdConfig
from mjx_surrogate.runs.config.schema import MOVED, Config, from_dict, to_dict, upgrade
from mjx_surrogate.runs.config.solver import SolverConfig, SysIdConfig
from mjx_surrogate.runs.config.system import SystemConfig
from mjx_surrogate.runs.config.task import Matrix, TaskConfig, Vector

__all__ = [
    "MOVED",
    "MPC_CONTROLLERS",
    "AnalysisConfig",
    "Config",
    "DataConfig",
    "ExperimentConfig",
    "MLPConfig",
    "MPCConfig",
    "MPCSysIdConfig",
    "Matrix",
    "ParallelConfig",
    "PodSindyConfig",
    "PointGoal",
    "SindyConfig",
    "SolverConfig",
    "SurrogateConfig",
    "SysIdConfig",
    "SystemConfig",
    "TaskConfig",
    "Vector",
    "check_finite",
    "from_dict",
    "to_dict",
    "upgrade",
]
