"""Process-wide runtime settings, applied by one explicit call (never at import).

The CLI, the benchmarks and the tests call :func:`configure_runtime` first; a notebook
should too, before its first JAX computation:

* ``XLA_FLAGS += --xla_cpu_use_fusion_emitters=false`` (jaxlib 0.10, whose XLA knows the
  flag; jaxlib 0.11's aborts on it, as on the next one): XLA's CPU fusion emitters slow MJX
  rollouts and their compiles on many-body models by large factors (docs/performance.md).
  Only effective before JAX starts its backend; skipped when the
  user's ``XLA_FLAGS`` already names the flag or ``MJX_SURROGATE_KEEP_XLA_FLAGS=1``.
* ``XLA_FLAGS += --xla_cpu_collective_call_warn_stuck_timeout_seconds=600``: on a busy
  2-core machine, devices of a CPU mesh reach a collective seconds apart, and XLA's default
  (20 s) prints "may be stuck" errors that XLA itself then retracts; a real hang is still
  ended by XLA's termination timeout.
* ``XLA_FLAGS += --xla_gpu_triton_gemm_any=true`` where a CUDA plugin of JAX is installed:
  the flag MuJoCo's MJX documentation recommends for GPUs (same rules as above).
* synchronous CPU dispatch: host callbacks inside jitted while loops (the native backend)
  can hang the CPU runtime at 0 % CPU with asynchronous dispatch (jax-ml/jax#25861).
* JAX's log of an exception raised inside a host callback (a user's black box, the native
  simulator) is silenced: the exception itself reaches the caller, and the command line
  reports it in one line naming the field (``system.entry``) instead of a traceback.
* MuJoCo's warning hook: a line search provokes many diverged trials, each of which MuJoCo
  would print; they are counted in :data:`MUJOCO_WARNINGS` (and surface as NaN states).
* JAX's persistent compilation cache in ``$MJX_SURROGATE_CACHE`` (default
  ``~/.cache/mjx_surrogate/jax``): a program compiled once (by any process) is loaded, not
  recompiled. ``MJX_SURROGATE_CACHE=off`` (or ``compile_cache=False``) switches it off.
  Programs with ``jax.pure_callback`` are not cached by JAX: a progress meter polled from
  inside a solve is one, and so is a user's NumPy function; the CLI drives its solves from
  the host instead (:mod:`mjx_surrogate.control.chunked`), so their programs are cached.
  The native backend's simulator is a named host call that the cache keeps
  (:mod:`mjx_surrogate.systems.host_call`).
  JAX does not cache tracing; the MJX step's own programs are exported into the same folder
  and loaded by later runs instead of traced (:mod:`mjx_surrogate.systems.exported_step`).
"""

from __future__ import annotations

import logging
import os

FUSION_FLAG = "--xla_cpu_use_fusion_emitters=false"
GPU_FLAG = "--xla_gpu_triton_gemm_any=true"
STUCK_FLAG = "--xla_cpu_collective_call_warn_stuck_timeout_seconds=600"
CUDA_PLUGINS = ("jax_cuda12_plugin", "jax_cuda13_plugin")
MUJOCO_WARNINGS = {"count": 0, "last": ""}


def _count_warning(msg: str) -> None:
    MUJOCO_WARNINGS["count"] += 1
    MUJOCO_WARNINGS["last"] = msg


def backend_started() -> bool:
    """Whether JAX has already created its backends (then XLA_FLAGS no longer apply)."""
    from jax._src import xla_bridge

    return bool(getattr(xla_bridge, "_backends", None))


def default_cache_dir() -> str | None:
    env = os.environ.get("MJX_SURROGATE_CACHE")
    if env is not None:
        return None if env.lower() in ("", "0", "off", "false", "no") else env
    return os.path.join(os.path.expanduser("~"), ".cache", "mjx_surrogate", "jax")


def _jaxlib_version() -> tuple[int, ...]:
    """The installed jaxlib's (major, minor), read without starting JAX."""
    from importlib.metadata import version

    return tuple(int(p) for p in version("jaxlib").split(".")[:2])


def cuda_plugin_installed() -> bool:
    import importlib.util

    return any(importlib.util.find_spec(name) is not None for name in CUDA_PLUGINS)


def native_compiler_options() -> dict | None:
    """XLA options for programs whose steps are host calls (the native backend, host
    functions): backend optimisation level 1, which compiles faster at about the same run
    time (docs/performance.md); None where ``XLA_FLAGS`` names a level, which then holds
    for every program."""
    if "xla_backend_optimization_level" in os.environ.get("XLA_FLAGS", ""):
        return None
    return {"xla_backend_optimization_level": 1}


def _add_flag(flag: str, applied: dict) -> None:
    flags = os.environ.get("XLA_FLAGS", "")
    if os.environ.get("MJX_SURROGATE_KEEP_XLA_FLAGS") or flag.split("=")[0] in flags:
        return
    if backend_started():
        applied["XLA_FLAGS"] = "not applied: the JAX backend had already started"
        return
    os.environ["XLA_FLAGS"] = (flags + " " + flag).strip()
    applied["XLA_FLAGS"] = os.environ["XLA_FLAGS"]


def configure_runtime(x64: bool | None = None, compile_cache: str | bool | None = None) -> dict:
    """Apply the settings above (idempotent); ``x64`` sets ``jax_enable_x64`` if given;
    ``compile_cache``: a folder, False (off), or None (the default folder).

    Returns what was applied, e.g. for a run's ``versions.json``.
    """
    applied: dict = {}
    if _jaxlib_version() < (0, 11):  # jaxlib 0.11's XLA refuses these flags and aborts
        _add_flag(FUSION_FLAG, applied)
        _add_flag(STUCK_FLAG, applied)
    if cuda_plugin_installed():
        _add_flag(GPU_FLAG, applied)
    import jax
    import mujoco

    logging.getLogger("jax._src.callback").setLevel(logging.CRITICAL)
    applied["callback_exception_log"] = "off"
    jax.config.update("jax_cpu_enable_async_dispatch", False)
    applied["jax_cpu_enable_async_dispatch"] = False
    mujoco.set_mju_user_warning(_count_warning)
    if x64 is not None:
        jax.config.update("jax_enable_x64", bool(x64))
    cache = default_cache_dir() if compile_cache in (None, True) else compile_cache or None
    if cache:
        try:
            os.makedirs(cache, exist_ok=True)
            jax.config.update("jax_compilation_cache_dir", cache)
            jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)
            applied["compilation_cache"] = cache
        except OSError as exc:  # a read-only home: run without the cache
            applied["compilation_cache"] = f"off ({exc})"
    else:
        applied["compilation_cache"] = "off"
    return applied
