"""Processes and hosts joined by ``jax.distributed`` (docs/scaling.md).

One command runs on a laptop, on several processes of one machine or on a cluster: every
process runs the same program (JAX's multi-controller model), the device mesh
(:mod:`mjx_surrogate.sharding`) spans the devices of all of them, and collectives between
CPU processes go through gloo. Only process 0 writes results (:func:`is_writer`); a sweep
gives whole experiments to processes in turn (:func:`my_share`), each on its own devices.
Nothing here runs at import: :func:`initialize` is called once, before any other JAX call.
"""

from __future__ import annotations

import os
from typing import Sequence, TypeVar

from mjx_surrogate.errors import ConfigError
from mjx_surrogate.runs.config import ParallelConfig

T = TypeVar("T")
_STATE = {"initialized": False, "timeout_s": 300, "barriers": 0}


def _from_env(value, name: str, cast=int):
    if value is not None:
        return value
    env = os.environ.get(name)
    if env is None or env == "":
        return None
    try:
        return cast(env)
    except ValueError:
        raise ConfigError(name, f"must be an integer, got {env!r}") from None


def initialize(pc: ParallelConfig, timeout_s: int = 300) -> dict:
    """Join this process to the others (idempotent; a no-op unless ``pc.distributed``).

    Unset rendezvous fields come from ``JAX_COORDINATOR_ADDRESS``, ``JAX_NUM_PROCESSES``
    and ``JAX_PROCESS_ID``, then from JAX's cluster auto-detection. Returns what was set
    up, for a run's ``versions.json``.
    """
    if not pc.distributed:
        return {"processes": 1}
    import jax

    if not _STATE["initialized"]:
        from mjx_surrogate.runtime import backend_started

        if backend_started():
            raise ConfigError(
                "parallel.distributed", "must be set up before any JAX computation (start a fresh process)"
            )
        jax.config.update("jax_cpu_collectives_implementation", "gloo")
        try:
            jax.distributed.initialize(
                coordinator_address=_from_env(pc.coordinator_address, "JAX_COORDINATOR_ADDRESS", str),
                num_processes=_from_env(pc.num_processes, "JAX_NUM_PROCESSES"),
                process_id=_from_env(pc.process_id, "JAX_PROCESS_ID"),
                initialization_timeout=timeout_s,
            )
        except (ValueError, RuntimeError) as exc:
            msg = " ".join(str(exc).split())[:200]
            raise ConfigError("parallel.distributed", f"could not join the processes ({msg})") from None
        _STATE["initialized"] = True
        _STATE["timeout_s"] = timeout_s
    return {
        "processes": jax.process_count(),
        "process_index": jax.process_index(),
        "devices": jax.device_count(),
        "local_devices": jax.local_device_count(),
    }


def process_index() -> int:
    import jax

    return jax.process_index()


def process_count() -> int:
    import jax

    return jax.process_count()


def is_writer() -> bool:
    """Whether this process writes results (process 0)."""
    return process_index() == 0


def my_share(items: Sequence[T]) -> list[T]:
    """This process's share of independent jobs: items i with i mod P == its index."""
    return [x for i, x in enumerate(items) if i % process_count() == process_index()]


def barrier(name: str, timeout_s: int | None = None) -> None:
    """Wait until every process reaches the barrier ``name`` (no-op in one process).

    The coordination service's barrier (JAX's distributed client; jax 0.10 exposes it only
    under ``jax._src``), not a collective: no Gloo connection is made to meet, and the
    processes then enter their next collective together. ``timeout_s`` defaults to the
    join's. Without the client (a JAX that moved it), a collective barrier is used.
    """
    if process_count() > 1:
        wait = _STATE["timeout_s"] if timeout_s is None else timeout_s
        _STATE["barriers"] += 1  # every process passes the same barriers in the same order
        barrier_id = f"{_STATE['barriers']}: {name}"
        try:
            from jax._src import distributed as jax_distributed

            client = jax_distributed.global_state.client
        except (ImportError, AttributeError):
            client = None
        if client is None:
            from jax.experimental import multihost_utils

            multihost_utils.sync_global_devices(barrier_id)
        else:
            client.wait_at_barrier(barrier_id, int(wait * 1000))
