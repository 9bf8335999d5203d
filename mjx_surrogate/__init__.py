"""mjx_surrogate: batched data-driven nonlinear optimal control on MuJoCo with JAX."""

import contextlib as _contextlib
import io as _io

from mjx_surrogate import _xla_flags  # noqa: F401  (must run before jax initialises)

# mujoco.mjx prints "Failed to import warp" to stdout when the optional GPU Warp backend
# is absent; that is expected on CPU, so the import is kept quiet.
with _contextlib.redirect_stdout(_io.StringIO()):
    from mujoco import mjx as _mjx  # noqa: F401

__version__ = "0.1.0"
