"""Black-box systems: MuJoCo models on two simulator backends (MJX and native MuJoCo),
and functions (a JAX step, or a host step behind a callback: :mod:`.function`).

One module per registered system (its MJCF, ``default_config()`` and task presets), the
black-box interface (:class:`BlackBox`) with its execution (:class:`Execution`), the
backends, and the registry. The project's own models are
written from the physical facts of the dm_control suite and the D2C 2.0 setting
(``shared/reference.md``). State convention everywhere: x = [qpos, qvel, act].
"""

from mjx_surrogate.systems.black_box import BlackBox
from mjx_surrogate.systems.execution import Execution
from mjx_surrogate.systems.function import FunctionSystem, from_jax, from_numpy
from mjx_surrogate.systems.registry import (
    default_config,
    from_mjcf,
    make_system,
    register_family,
    register_system,
    system_names,
    task_presets,
)
from mjx_surrogate.systems.spec import SystemDefaults
from mjx_surrogate.systems.system import BACKENDS, System, build_system

__all__ = [
    "BACKENDS",
    "BlackBox",
    "Execution",
    "FunctionSystem",
    "System",
    "SystemDefaults",
    "build_system",
    "default_config",
    "from_jax",
    "from_mjcf",
    "from_numpy",
    "make_system",
    "register_family",
    "register_system",
    "system_names",
    "task_presets",
]
