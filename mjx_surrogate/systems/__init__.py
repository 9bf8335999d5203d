"""Black-box MuJoCo systems on two simulator backends (MJX and native MuJoCo)."""

from mjx_surrogate.systems.registry import (SYSTEM_NAMES, default_config, from_mjcf,
                                            make_system)
from mjx_surrogate.systems.system import BACKENDS, System, build_system

__all__ = ["BACKENDS", "SYSTEM_NAMES", "System", "build_system", "default_config",
           "from_mjcf", "make_system"]
