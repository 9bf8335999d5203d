"""The ``system`` section: which black box to simulate and how."""

from __future__ import annotations

import dataclasses
import math
from typing import Literal, Optional

from mjx_surrogate.errors import ConfigError


@dataclasses.dataclass(frozen=True)
class SystemConfig:
    """Which black box to simulate and how.

    name: a registered system (pendulum, cartpole, fish, swimmerN; the function black
      boxes lorenz, f8, and the PDEs burgersN, allen_cahnN, allen_cahn2dN on N cells per
      side), "mjcf" (the user's MJCF file) or "python" (the user's function).
    mjcf_path: the user's MJCF file, with name="mjcf".
    model_copy: a compiled copy of that model (a run folder's model.mjb), simulated instead
      of the file at mjcf_path, which may have changed since; a replay sets it.
    entry: with name="python", the user's black box as MODULE:ATTRIBUTE or
      FILE.py:ATTRIBUTE, a FunctionSystem or a function returning one (from_numpy,
      from_jax; docs/function_systems.md).
    source_sha256: the SHA-256 of the entry's file, recorded by a run; a replay refuses
      to run when the file has changed.
    backend: "mjx", "native", or "auto" (the measured faster one on the CPU); a function
      black box runs as it is given ("auto").
    substeps: physics steps per control step (None: the system's default, 1 for "mjcf").
    control_dt: the control time step in seconds instead of substeps (a multiple of the
      physics time step).
    timestep: physics time step override in seconds (None: the model's).
    native_threads: threads of the native backend (None: all cores).
    """

    name: str = "pendulum"
    mjcf_path: Optional[str] = None
    model_copy: Optional[str] = None
    entry: Optional[str] = None
    source_sha256: Optional[str] = None
    backend: Literal["auto", "mjx", "native"] = "auto"
    substeps: Optional[int] = None
    control_dt: Optional[float] = None
    timestep: Optional[float] = None
    native_threads: Optional[int] = None

    def check(self) -> None:
        """Refuses bad values (ConfigError naming the field); the function black boxes' own
        rules are :func:`mjx_surrogate.runs.validation.validate_static`'s (they need the registry)."""
        if self.substeps is not None and self.substeps < 1:
            raise ConfigError("system.substeps", f"must be >= 1, got {self.substeps}")
        for field, v in (("system.timestep", self.timestep), ("system.control_dt", self.control_dt)):
            if v is not None and not (math.isfinite(v) and v > 0):
                raise ConfigError(field, f"must be a finite number of seconds > 0, got {v}")
        if self.substeps is not None and self.control_dt is not None:
            raise ConfigError("system.control_dt", "give system.control_dt or system.substeps, not both")
        if self.native_threads is not None and self.native_threads < 1:
            raise ConfigError(
                "system.native_threads", f"must be >= 1 (or unset: all cores), got {self.native_threads}"
            )
