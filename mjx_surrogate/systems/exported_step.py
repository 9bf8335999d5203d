"""The MJX step's programs kept on disk, so that a second run does not trace them again.

JAX's persistent compilation cache (:mod:`mjx_surrogate.runtime`) spares a second run the
XLA compile but not the tracing: the key of a cached program is its lowered text, so every
run first traces the whole solve, and most of that is the MJX step, batched by ``vmap`` for
each batch size the solve uses (most of what a cached run spends before its first
iteration; measured in docs/performance.md, "Compile times").

:func:`with_exported_batches` wraps a step so that it calls ``step``, and under ``vmap``
``vmap(step)`` for that batch size, as :mod:`jax.export` programs, serialised once into
``<compilation cache>/exported_steps`` and deserialised by later runs (microseconds) instead
of being traced. Its derivatives trace the step itself (forward mode, as ``jacfwd``); the
exact oracle's Jacobians (:attr:`System.mjx_jacobians`) are exported the same way. Nested
vmaps (a multi-start solve around a vmapped identification) merge into one batch. Only for
work on one device: programs spread over a mesh trace the step and its batch
(:func:`with_batch_rule`). A native system's MJX step (its exact oracle) is wrapped around
:func:`lazily` built steps, so that a run which finds every program on disk never builds
the MJX model, a cost of its own.

A program's file name hashes everything it depends on: the compiled model, the substeps,
the batch shape and dtypes, the precision mode (``jax_enable_x64`` sets the MJX model's
dtype), the platform, the versions of jax, jaxlib, mujoco and mujoco-mjx, and this
package's MJX backend source. With the compilation cache off nothing is written or read.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.metadata
import inspect
import os
import tempfile
from typing import Callable

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from jax import export

SUBDIR = "exported_steps"


def cache_folder() -> str | None:
    """``<jax_compilation_cache_dir>/exported_steps``, or None when the cache is off."""
    base = jax.config.jax_compilation_cache_dir
    return os.path.join(base, SUBDIR) if base else None


def _model_digest(mj_model: mujoco.MjModel, substeps: int) -> str:
    from mjx_surrogate.systems import backend_mjx  # its source is part of the key

    buf = np.zeros(mujoco.mj_sizeModel(mj_model), np.uint8)
    mujoco.mj_saveModel(mj_model, None, buf)
    h = hashlib.sha256(buf.tobytes())
    versions = [importlib.metadata.version(p) for p in ("jax", "jaxlib", "mujoco", "mujoco-mjx")]
    h.update(repr((substeps, versions, inspect.getsource(backend_mjx))).encode())
    return h.hexdigest()[:32]


def lazily(build: Callable[[], Callable]) -> Callable:
    """A function that calls ``build()``'s result, built on its first call: a step whose
    MJX model costs seconds to build is then built only to be exported or differentiated,
    not by a run that loads every program it needs."""
    built = functools.cache(build)
    return lambda *args: built()(*args)


def _both_batched(axis_size: int, in_batched, x: jax.Array, u: jax.Array) -> tuple:
    """x and u with the vmapped axis leading (an unbatched one broadcast to it)."""
    return tuple(a if b else jnp.broadcast_to(a, (axis_size,) + a.shape) for a, b in zip((x, u), in_batched))


def _all_batched(out):
    """A vmap rule's result: ``out`` and its every leaf batched."""
    return out, jax.tree.map(lambda _: True, out)


def with_exported_batches(
    step: Callable,
    mj_model: mujoco.MjModel,
    substeps: int,
    tag: str = "step",
    batch: Callable | None = None,
) -> Callable:
    """``step(x[nx], u[nu])`` (any function of the state and control of ``mj_model``, e.g.
    its Jacobians, named by ``tag``) whose calls and ``vmap`` run disk-cached exports of
    ``step`` and of ``batch(x [B, nx], u [B, nu])`` (default ``vmap(step)``); its
    attribute ``batched(x [B, nx], u [B, nu])`` runs the batch's program alone (not
    differentiable)."""
    batch = batch or jax.vmap(step)
    digest = _model_digest(mj_model, substeps) + tag
    programs: dict = {}

    def program(x: jax.ShapeDtypeStruct, u: jax.ShapeDtypeStruct) -> export.Exported:
        """The export of ``step`` (x [nx]) or of ``vmap(step)`` (x [B, nx])."""
        key = (x.shape, x.dtype.name, u.shape, u.dtype.name, jax.default_backend(), jax.config.jax_enable_x64)
        if key in programs:
            return programs[key]
        folder = cache_folder()
        path = None
        if folder:
            name = hashlib.sha256(repr((digest, key)).encode()).hexdigest()[:40]
            path = os.path.join(folder, name + ".jaxexport")
            try:
                with open(path, "rb") as f:
                    programs[key] = export.deserialize(bytearray(f.read()))
                return programs[key]
            except (OSError, ValueError):
                pass  # not there yet (or unreadable): export it afresh
        exp = export.export(jax.jit(batch if len(x.shape) == 2 else step))(x, u)
        if path:
            try:
                os.makedirs(folder, exist_ok=True)
                fd, tmp = tempfile.mkstemp(dir=folder)
                with os.fdopen(fd, "wb") as f:
                    f.write(exp.serialize())
                os.replace(tmp, path)  # whole files only, also with concurrent writers
            except OSError:
                pass  # a read-only cache: run without it
        programs[key] = exp
        return exp

    def call(x: jax.Array, u: jax.Array) -> jax.Array:
        shape = lambda a: jax.ShapeDtypeStruct(a.shape, a.dtype)  # noqa: E731
        return program(shape(x), shape(u)).call(x, u)

    return with_batch_rule(step, call, call)


def with_batch_rule(step: Callable, call: Callable, call_batch: Callable) -> Callable:
    """``step(x[nx], u[nu])`` run as ``call(x, u)``, and under ``vmap`` (nested vmaps merged
    into one batch) as ``call_batch(x [B, nx], u [B, nu])``; its derivatives trace ``step``
    itself. Its attribute ``batched`` is ``call_batch`` with that rule (not differentiable).
    ``with_batch_rule(step, step, batch)`` gives a plain step a batch of its own (a mesh's)."""

    @jax.custom_batching.custom_vmap
    def batched(x: jax.Array, u: jax.Array) -> jax.Array:
        """x [B, nx], u [B, nu] -> [B, nx] by ``call_batch``."""
        return call_batch(x, u)

    @batched.def_vmap
    def _batched_vmap(axis_size, in_batched, x, u):  # an outer vmap: one batch of S B
        x, u = _both_batched(axis_size, in_batched, x, u)
        S, B = x.shape[:2]
        out = batched(x.reshape((S * B,) + x.shape[2:]), u.reshape((S * B,) + u.shape[2:]))
        return _all_batched(jax.tree.map(lambda o: o.reshape((S, B) + o.shape[1:]), out))

    @jax.custom_batching.custom_vmap
    def one(x: jax.Array, u: jax.Array) -> jax.Array:
        return call(x, u)

    @one.def_vmap
    def _one_vmap(axis_size, in_batched, x, u):
        return _all_batched(batched(*_both_batched(axis_size, in_batched, x, u)))

    @jax.custom_jvp
    def differentiable(x: jax.Array, u: jax.Array):
        return one(x, u)

    @differentiable.defjvp
    def _differentiable_jvp(primals, tangents):  # derivatives trace the step itself
        return jax.jvp(step, primals, tangents)

    # custom_vmap traces the function it wraps before its rule runs: vmap(differentiable)
    # traces (exports) the unbatched call too. ``batched`` traces only the batch's.
    differentiable.batched = batched
    return differentiable
