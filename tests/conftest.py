"""Test configuration: float64 everywhere (references are float64 NumPy / MuJoCo C), the
runtime configured as the CLI does.

Strict promotion does not fit this code base: MJX itself mixes bool and float arrays
(``jax_numpy_dtype_promotion='strict'`` fails inside ``mjx.step``) and the solver
broadcasts per-channel limits [nu] against [T, nu] by design (rank promotion). Tests
assert output dtypes instead, and one subprocess smoke test runs the default precision
(float32).

Garbage collection: a worker's heap grows to millions of long-lived objects (JAX's caches,
traced programs, MuJoCo models), and with Python's default thresholds each full collection
walks all of them again. After collection the objects imported so far are frozen (never
walked again) and collections run less often: in a full suite run the workers spent about
120 s of CPU in the collector with the defaults (measured with ``gc.callbacks``).
"""

import gc
import os
import sys

os.environ.setdefault("MPLBACKEND", "Agg")
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # tests/reference_*.py

from mjx_surrogate.runtime import configure_runtime  # noqa: E402

# LLVM at -O0 for the tests' programs (the XLA graph optimisations are unchanged): the
# suite is compile-bound, and -O0 takes 28 % off the fast tier's time on 2 cores.
# test_structure's float32 end-to-end run drops it, so that code compiled as users get it
# is run too; a user's XLA_FLAGS naming the level is kept.
OPT_FLAG = "--xla_backend_optimization_level=0"
if "xla_backend_optimization_level" not in os.environ.get("XLA_FLAGS", ""):
    os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "") + " " + OPT_FLAG).strip()
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
# leaves one worker idle at the end.
_LONGEST_FIRST = (
    "test_reproduce.py",
    "test_sharding.py",
    "test_docs.py",
    "test_thirdparty.py",
    "test_function_cli.py",
    "test_notebook.py",
)


def pytest_collection_finish(session):
    gc.collect()
    gc.freeze()
    gc.set_threshold(50_000, 20, 10)


def pytest_collection_modifyitems(config, items):
    """The files above first, then the other files with slow tests, then the files of fast
    tests only: the last tests handed out are short, so the two workers end together.
    A file's tests stay together, in their order (module fixtures are built once)."""
    rank = {name: i for i, name in enumerate(_LONGEST_FIRST)}
    slow = {item.path.name for item in items if item.get_closest_marker("slow")}
    items.sort(key=lambda item: (rank.get(item.path.name, len(rank)), item.path.name not in slow))
