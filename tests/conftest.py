"""Test configuration: float64 everywhere (references are float64 NumPy / MuJoCo C).

Strict dtype promotion (``jax_numpy_dtype_promotion='strict'``) is not used because MJX
itself mixes bool and float arrays internally; our tests assert output dtypes instead.
"""

import os

os.environ.setdefault("MPLBACKEND", "Agg")

import mjx_surrogate  # noqa: E402,F401  (XLA flags before jax initialises)
import jax  # noqa: E402
import pytest  # noqa: E402

jax.config.update("jax_enable_x64", True)


@pytest.fixture(scope="session")
def systems():
    """Systems built once per session (MJX models are put in float64)."""
    from mjx_surrogate.systems import make_system

    cache = {}

    def get(name, backend="mjx", **kw):
        key = (name, backend, tuple(sorted(kw.items())))
        if key not in cache:
            cache[key] = make_system(name, backend=backend, **kw)
        return cache[key]

    return get
