"""How and where a black box's batched work runs, apart from what the black box is.

A system (:class:`~.system.System`, :class:`~.function.FunctionSystem`) is the map
x_{t+1} = f(x_t, u_t) with its sizes and limits; its :class:`Execution` says which
simulator steps it, with how many host threads, over which devices, and with which XLA
options its programs compile. An execution is a value: equal settings compare and hash
equal, so a cache of systems by content (:func:`~.system.build_system`) keys on it.
"""

from __future__ import annotations

import dataclasses

from jax.sharding import Mesh

from mjx_surrogate import sharding
from mjx_surrogate.errors import ConfigError
from mjx_surrogate.runtime import native_compiler_options

TRACED_BACKENDS = ("mjx", "jax")  # steps that are JAX programs (MJX, a JAX function)
HOST_BACKENDS = ("native", "host")  # steps that call the host (native MuJoCo, a host function)


@dataclasses.dataclass(frozen=True)
class Execution:
    """backend: "mjx" or "native" for a MuJoCo model, "jax" or "host" for a step function.
    threads: host threads that step one batch (native MuJoCo's pool; 1 elsewhere).
    mesh: the devices that batched work is spread over (None: one device)."""

    backend: str
    threads: int = 1
    mesh: Mesh | None = None

    def __post_init__(self):
        if self.backend not in TRACED_BACKENDS + HOST_BACKENDS:
            valid = TRACED_BACKENDS + HOST_BACKENDS
            raise ConfigError("system.backend", f"unknown backend {self.backend!r}; valid: {valid}")
        if not isinstance(self.threads, int) or self.threads < 1:
            raise ConfigError("system.native_threads", f"must be >= 1, got {self.threads!r}")

    @property
    def on_host(self) -> bool:
        """Whether each step is a host call: a batch is spread over the host's threads by the
        call itself, so a ``vmap`` over several solves adds no parallelism."""
        return self.backend in HOST_BACKENDS

    @property
    def compiler_options(self) -> dict | None:
        """XLA options for programs on this execution: host-call programs compile at XLA's
        backend optimisation level 1 (faster to compile at about the same run time,
        docs/performance.md "Compile times"; :func:`runtime.native_compiler_options`);
        None (XLA's defaults) for traced steps."""
        return native_compiler_options() if self.on_host else None

    def over(self, mesh: Mesh | None) -> Execution:
        """This execution with its batched work spread over ``mesh``: every device for a
        traced step, the first device of each process for a host step
        (:func:`sharding.one_device_per_process`)."""
        spread = sharding.one_device_per_process(mesh) if self.on_host else mesh
        return dataclasses.replace(self, mesh=spread)

    def on_one_device(self) -> Execution:
        """This execution with its batched work kept on one device (inside a computation that
        is itself spread over the mesh)."""
        return dataclasses.replace(self, mesh=None)


class OnExecution:
    """What a black box reads from its :class:`Execution` (``self.execution``): its
    ``backend``, ``mesh`` and ``compiler_options``."""

    execution: Execution

    @property
    def backend(self) -> str:
        """The backend: "mjx" or "native" for a MuJoCo model, "jax" or "host" for a function."""
        return self.execution.backend

    @property
    def mesh(self) -> Mesh | None:
        """The devices that batched work is spread over; None: one device."""
        return self.execution.mesh

    @property
    def compiler_options(self) -> dict | None:
        """XLA options for programs on this black box (:attr:`Execution.compiler_options`)."""
        return self.execution.compiler_options
