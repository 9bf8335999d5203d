"""Host functions called from compiled programs under a stable name, so XLA can cache them.

``jax.pure_callback`` embeds a pointer to its Python function in the program, and JAX
never writes such a program to its persistent compilation cache: every process compiles
the native backend's solves again (seconds per robot). :func:`call` instead lowers to
one XLA FFI custom call, ``mjx_surrogate_host_call``, whose ``key`` attribute names the
function in this process's registry (:func:`register`). The program then holds only the
name and the key, and a later process that registers the same key (the same model, say)
loads it from the cache.

The handler is a ``ctypes`` function speaking XLA's FFI C API (``xla/ffi/api/c_api.h``,
shipped in jaxlib's include folder): it answers XLA's version query, wraps the argument
buffers as read-only NumPy arrays without copying, calls the registered function and
copies its results into the result buffers; an exception becomes an FFI error carrying
its type and message. It is registered once per process, for the CPU only; elsewhere
(another platform, or an FFI API this module does not know) :func:`call` is
``jax.pure_callback``, with the same results.

A key must determine the function's results: the same key means the same function.
"""

from __future__ import annotations

import ctypes
import threading
from typing import Callable, Sequence

import jax
import numpy as np

TARGET = "mjx_surrogate_host_call"
_API_MAJOR, _API_MINOR = 0, 1  # the FFI API whose structures are declared below

# XLA_FFI_DataType -> NumPy (xla_data.proto's PrimitiveType numbers)
_DTYPES = {
    1: np.bool_,
    2: np.int8,
    3: np.int16,
    4: np.int32,
    5: np.int64,
    6: np.uint8,
    7: np.uint16,
    8: np.uint32,
    9: np.uint64,
    10: np.float16,
    11: np.float32,
    12: np.float64,
    15: np.complex64,
    18: np.complex128,
}
_METADATA_EXTENSION, _EXECUTE, _ATTR_STRING, _ERROR_UNKNOWN = 1, 3, 4, 2


class _ExtensionBase(ctypes.Structure):
    pass


_ExtensionBase._fields_ = [
    ("struct_size", ctypes.c_size_t),
    ("type", ctypes.c_int),
    ("next", ctypes.POINTER(_ExtensionBase)),
]


class _ApiVersion(ctypes.Structure):
    _fields_ = [
        ("struct_size", ctypes.c_size_t),
        ("extension_start", ctypes.c_void_p),
        ("major_version", ctypes.c_int),
        ("minor_version", ctypes.c_int),
    ]


class _Metadata(ctypes.Structure):
    _fields_ = [("struct_size", ctypes.c_size_t), ("api_version", _ApiVersion), ("traits", ctypes.c_uint32)]


class _MetadataExtension(ctypes.Structure):
    _fields_ = [("extension_base", _ExtensionBase), ("metadata", ctypes.POINTER(_Metadata))]


class _Buffer(ctypes.Structure):
    _fields_ = [
        ("struct_size", ctypes.c_size_t),
        ("extension_start", ctypes.c_void_p),
        ("dtype", ctypes.c_int),
        ("data", ctypes.c_void_p),
        ("rank", ctypes.c_int64),
        ("dims", ctypes.POINTER(ctypes.c_int64)),
    ]


class _List(ctypes.Structure):  # XLA_FFI_Args and XLA_FFI_Rets: buffers behind void*
    _fields_ = [
        ("struct_size", ctypes.c_size_t),
        ("extension_start", ctypes.c_void_p),
        ("size", ctypes.c_int64),
        ("types", ctypes.POINTER(ctypes.c_int)),
        ("items", ctypes.POINTER(ctypes.POINTER(_Buffer))),
    ]


class _ByteSpan(ctypes.Structure):
    _fields_ = [("ptr", ctypes.c_void_p), ("len", ctypes.c_size_t)]


class _Attrs(ctypes.Structure):
    _fields_ = [
        ("struct_size", ctypes.c_size_t),
        ("extension_start", ctypes.c_void_p),
        ("size", ctypes.c_int64),
        ("types", ctypes.POINTER(ctypes.c_int)),
        ("names", ctypes.POINTER(ctypes.POINTER(_ByteSpan))),
        ("attrs", ctypes.POINTER(ctypes.c_void_p)),
    ]


class _ErrorCreateArgs(ctypes.Structure):
    _fields_ = [
        ("struct_size", ctypes.c_size_t),
        ("extension_start", ctypes.c_void_p),
        ("message", ctypes.c_char_p),
        ("errc", ctypes.c_int),
    ]


_ErrorCreate = ctypes.CFUNCTYPE(ctypes.c_void_p, ctypes.POINTER(_ErrorCreateArgs))


class _Api(ctypes.Structure):  # the leading fields of XLA_FFI_Api
    _fields_ = [
        ("struct_size", ctypes.c_size_t),
        ("extension_start", ctypes.c_void_p),
        ("api_version", _ApiVersion),
        ("internal_api", ctypes.c_void_p),
        ("error_create", _ErrorCreate),
    ]


class _CallFrame(ctypes.Structure):
    _fields_ = [
        ("struct_size", ctypes.c_size_t),
        ("extension_start", ctypes.POINTER(_ExtensionBase)),
        ("api", ctypes.POINTER(_Api)),
        ("ctx", ctypes.c_void_p),
        ("stage", ctypes.c_int),
        ("args", _List),
        ("rets", _List),
        ("attrs", _Attrs),
        ("future", ctypes.c_void_p),
    ]


_Handler = ctypes.CFUNCTYPE(ctypes.c_void_p, ctypes.POINTER(_CallFrame))
_REGISTRY: dict[str, Callable] = {}
_STATE: dict = {"handler": None, "error": None}
_LOCK = threading.Lock()


class _View:
    """Exposes an FFI buffer through NumPy's array interface (no copy)."""

    def __init__(self, buf: _Buffer, readonly: bool):
        dtype = np.dtype(_DTYPES[buf.dtype])
        shape = tuple(buf.dims[i] for i in range(buf.rank))
        self.__array_interface__ = {
            "version": 3,
            "shape": shape,
            "typestr": dtype.str,
            "data": (buf.data or 0, readonly),
        }


def _array(buf: _Buffer, readonly: bool) -> np.ndarray:
    """A NumPy view of an FFI buffer (row-major, XLA's default layout for custom calls)."""
    return np.asarray(_View(buf, readonly))


def _key(attrs: _Attrs) -> str:
    for i in range(attrs.size):
        name = attrs.names[i].contents
        if ctypes.string_at(name.ptr, name.len) == b"key" and attrs.types[i] == _ATTR_STRING:
            span = ctypes.cast(attrs.attrs[i], ctypes.POINTER(_ByteSpan)).contents
            return ctypes.string_at(span.ptr, span.len).decode()
    raise KeyError("the call has no string attribute 'key'")


def _execute(frame: _CallFrame) -> None:
    fn = _REGISTRY[_key(frame.attrs)]
    args = []
    for i in range(frame.args.size):
        args.append(_array(frame.args.items[i].contents, readonly=True))
    results = fn(*args)
    results = (results,) if isinstance(results, np.ndarray) or np.isscalar(results) else tuple(results)
    if len(results) != frame.rets.size:
        raise ValueError(f"{len(results)} results returned, {frame.rets.size} expected")
    for i, r in enumerate(results):
        out = _array(frame.rets.items[i].contents, readonly=False)
        np.copyto(out, np.asarray(r).reshape(out.shape), casting="same_kind")


def _handle(frame_ptr) -> int | None:
    frame = frame_ptr.contents
    ext = frame.extension_start
    if ext and ext.contents.type == _METADATA_EXTENSION:  # XLA asks which API we speak
        meta = ctypes.cast(ext, ctypes.POINTER(_MetadataExtension)).contents.metadata.contents
        meta.api_version.major_version, meta.api_version.minor_version = _API_MAJOR, _API_MINOR
        meta.traits = 0
        return None
    if frame.stage != _EXECUTE:
        return None
    try:
        _execute(frame)
        return None
    except BaseException as exc:  # an error for XLA to raise, never an unwinding through C
        msg = f"{type(exc).__name__}: {exc}".encode(errors="replace")
        args = _ErrorCreateArgs(ctypes.sizeof(_ErrorCreateArgs), None, msg, _ERROR_UNKNOWN)
        return frame.api.contents.error_create(ctypes.byref(args))


def available() -> bool:
    """Whether the named target is registered with XLA for the CPU (registering it on the
    first call); False where the FFI API is not one this module speaks."""
    with _LOCK:
        if _STATE["handler"] is None and _STATE["error"] is None:
            try:
                handler = _Handler(_handle)
                jax.ffi.register_ffi_target(TARGET, jax.ffi.pycapsule(handler), platform="cpu")
                _STATE["handler"] = handler  # kept alive: XLA holds its address
            except Exception as exc:  # pragma: no cover - depends on the installed jaxlib
                _STATE["error"] = exc
        return _STATE["handler"] is not None


def register(key: str, fn: Callable) -> Callable:
    """``fn`` under ``key`` for this process (the first one registered under a key stays:
    a key determines the results). Returns the registered function."""
    return _REGISTRY.setdefault(key, fn)


def call(
    key: str,
    fn: Callable,
    result_shape_dtypes: jax.ShapeDtypeStruct | Sequence[jax.ShapeDtypeStruct],
    *args: jax.Array,
    vmap_method: str,
):
    """``fn(*args)`` on the host from traced code, as ``jax.pure_callback(fn, ...)`` would,
    under the name ``key`` (registered here), so that the program can be cached."""
    fn = register(key, fn)
    if jax.default_backend() == "cpu" and available():
        return jax.ffi.ffi_call(TARGET, result_shape_dtypes, vmap_method=vmap_method)(*args, key=key)
    return jax.pure_callback(fn, result_shape_dtypes, *args, vmap_method=vmap_method)
