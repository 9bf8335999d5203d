"""Batch axes over devices: one mesh axis, ``jax.shard_map``, sums reduced by ``psum``.

Every batched computation of the engine has a leading batch axis (identification
samples, line-search step sizes, multi-start solves, data-set trajectories, MLP seeds).
With a :class:`jax.sharding.Mesh` of D devices along the single axis :data:`AXIS`:

* :func:`map_batch` runs ``fn`` on each device's slice of the batch axis (``shard_map``,
  fully manual: a host callback such as the native backend's runs once per device, on
  the host that owns the device, with that device's slice); the outputs are gathered;
* :func:`sum_over_batch` reduces per-device sums with one ``psum``: the least-squares fit
  of :mod:`mjx_surrogate.identification.sysid` sums its sufficient statistics (Z'Z, Z'Y) this way, so
  raw samples never leave their device.

A batch whose size is not a multiple of D is padded (edge copies for maps, zero weights
for sums) and the padding dropped. ``mesh=None`` (or a mesh of one device) runs ``fn`` as
it is: one device, nothing changes. Over processes joined by :mod:`jax.distributed` the
mesh spans every process's devices and the same code runs unchanged (docs/scaling.md).
"""

from __future__ import annotations

from typing import Any, Callable, Sequence

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding
from jax.sharding import PartitionSpec as P

from mjx_surrogate.errors import ConfigError

AXIS = "batch"


def device_mesh(
    devices: int | Sequence[jax.Device] | None = None, available: Sequence[jax.Device] | None = None
) -> Mesh | None:
    """A one-axis mesh over ``devices``: None = every device of ``available`` (default:
    every visible device, of every process), an int n = the first n of them, or explicit
    devices. One device gives None."""
    available = jax.devices() if available is None else list(available)
    if devices is None:
        chosen = available
    elif isinstance(devices, int):
        if not 1 <= devices <= len(available):
            raise ConfigError(
                "parallel.devices", f"must be between 1 and {len(available)} (visible devices), got {devices}"
            )
        chosen = available[:devices]
    else:
        chosen = list(devices)
    if len(chosen) == 1:
        return None
    return Mesh(np.asarray(chosen), (AXIS,))


def one_device_per_process(mesh: Mesh | None) -> Mesh | None:
    """The mesh narrowed to the first of its devices in each process (None if one remains).

    For the native backend. Made for ``jax.pure_callback``, which hands a callback its
    arguments on the process's first CPU device: callbacks of two devices of one process
    waited on the same device, and in a reproduction this deadlocked (both idle, 0 % CPU).
    The simulator's named host call reads each device's buffers, and the rule stays: one
    device per process keeps the spread across hosts; MuJoCo's own threads use the cores.
    """
    if mesh is None:
        return None
    firsts: dict[int, jax.Device] = {}
    for d in mesh.devices.flat:
        firsts.setdefault(d.process_index, d)
    return device_mesh(list(firsts.values()))


def on_one_device(*arrays: jax.Array) -> tuple[jax.Array, ...]:
    """``arrays`` gathered whole on this process's first device, for a dense solve that
    should not be partitioned: XLA splits the SVD of a least-squares problem whose rows are
    spread over 2 CPU devices into a program 3.3x slower than on one (9000 x 2701, float64,
    24.7 s against 7.4 s), and the same solves mapped over two CPU devices at once have hung
    (two LAPACK kernels at once: docs/performance.md, "No LAPACK in compiled programs").
    An array spread over several processes is returned as it is."""
    device = jax.local_devices()[0]
    whole = lambda a: not isinstance(a, jax.Array) or a.is_fully_addressable  # noqa: E731
    return tuple(jax.device_put(a, device) if whole(a) else a for a in arrays)


def size(mesh: Mesh | None) -> int:
    """Number of devices the batch axes are spread over (1 without a mesh)."""
    return 1 if mesh is None else int(mesh.shape[AXIS])


def replicated(mesh: Mesh | None):
    """The sharding of an array held whole by every device of ``mesh`` (None: default)."""
    return None if mesh is None else NamedSharding(mesh, P())


def _padded(n: int, d: int) -> int:
    return -(-n // d) * d


def _pad_edge(a: jax.Array, n_pad: int) -> jax.Array:
    if n_pad == a.shape[0]:
        return a
    return jnp.concatenate([a, jnp.repeat(a[-1:], n_pad - a.shape[0], axis=0)])


def map_batch(fn: Callable, mesh: Mesh | None, *batched: Any, rest: tuple = ()) -> Any:
    """fn(*batched, *rest) with every leaf of ``batched`` split along its leading axis
    (size B, the same for all) over the mesh, and ``rest`` replicated. fn must map a
    batch of b to outputs with leading axis b; returns the outputs for all B."""
    if size(mesh) == 1:
        return fn(*batched, *rest)
    B = jax.tree.leaves(batched)[0].shape[0]
    n_pad = _padded(B, size(mesh))
    padded = jax.tree.map(lambda a: _pad_edge(a, n_pad), batched)
    mapped = jax.shard_map(
        lambda b, r: fn(*b, *r),
        mesh=mesh,
        in_specs=(P(AXIS), P()),
        out_specs=P(AXIS),
        check_vma=False,
    )(padded, rest)
    return jax.tree.map(lambda a: a[:B], mapped)


def over_leading_axis(fn: Callable, *xs: Any, lockstep: bool) -> Any:
    """fn over the leading axis of every leaf of ``xs``: side by side (``vmap``), or, with
    ``lockstep`` false, one after another (``lax.map``), where each item runs its own loops
    to their own ends instead of a batched ``while_loop`` running every item until the last
    one stops, and ``lax.cond`` keeps one branch."""
    if lockstep:
        return jax.vmap(fn)(*xs)
    return jax.lax.map(lambda a: fn(*a), xs)


def sum_over_batch(fn: Callable, mesh: Mesh | None, batched: Any, rest: tuple = ()) -> Any:
    """sum_i fn(batched_i, weights_i, *rest) where ``fn(chunk, weights, *rest)`` returns
    weighted sums over its chunk of the batch (leading axis); each device sums its chunk
    and one ``psum`` adds the devices' sums. Padding rows have weight 0; without a mesh
    there is no padding and ``weights`` is None (all ones)."""
    B = jax.tree.leaves(batched)[0].shape[0]
    dtype = jax.tree.leaves(batched)[0].dtype
    if size(mesh) == 1:
        return fn(batched, None, *rest)  # no padding: no weights
    n_pad = _padded(B, size(mesh))
    padded = jax.tree.map(
        lambda a: jnp.concatenate([a, jnp.zeros((n_pad - B,) + a.shape[1:], a.dtype)]), batched
    )
    weights = jnp.concatenate([jnp.ones((B,), dtype), jnp.zeros((n_pad - B,), dtype)])
    return jax.shard_map(
        lambda b, w, r: jax.lax.psum(fn(b, w, *r), AXIS),
        mesh=mesh,
        in_specs=(P(AXIS), P(AXIS), P()),
        out_specs=P(),
        check_vma=False,
    )(padded, weights, rest)


CHUNK_NUMBERS = 2**24  # numbers per array of one chunk of :func:`vmap_in_chunks` (128 MiB in float64)


def vmap_in_chunks(fn: Callable, xs: Any, numbers_per_item: int) -> Any:
    """``jax.vmap(fn)(xs)`` over the leading axis, in sequential chunks (``lax.map``'s
    ``batch_size``) where the whole batch's arrays, ``numbers_per_item`` numbers an item,
    would exceed :data:`CHUNK_NUMBERS`: a grid of many cells keeps its peak memory to a
    chunk's; a batch that fits is the plain vmap."""
    B = jax.tree.leaves(xs)[0].shape[0]
    k = max(1, CHUNK_NUMBERS // max(1, numbers_per_item))
    return jax.vmap(fn)(xs) if k >= B else jax.lax.map(fn, xs, batch_size=k)
