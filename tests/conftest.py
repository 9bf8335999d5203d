"""Test configuration: float64 everywhere (references are float64 NumPy / MuJoCo C), the
runtime configured as the CLI does.

Strict promotion does not fit this code base: MJX itself mixes bool and float arrays
(``jax_numpy_dtype_promotion='strict'`` fails inside ``mjx.step``) and the solver
broadcasts per-channel limits [nu] against [T, nu] by design (rank promotion). Tests
assert output dtypes instead, and one subprocess smoke test runs the default precision
(float32).
"""

import os
import sys

os.environ.setdefault("MPLBACKEND", "Agg")
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # tests/reference_*.py

from mjx_surrogate.runtime import configure_runtime  # noqa: E402

configure_runtime(x64=True)

import pytest  # noqa: E402


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


# The longest tests first, so that with two xdist workers none of them starts last and
# leaves one worker idle at the end (the order is otherwise unchanged).
_LONGEST_FIRST = (
    "test_reproduce.py",
    "test_sharding.py",
    "test_docs.py",
    "test_thirdparty.py",
    "test_function_cli.py",
    "test_notebook.py",
)


def pytest_collection_modifyitems(config, items):
    rank = {name: i for i, name in enumerate(_LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))
