"""Structure the code base promises: one-way imports, no import-time global state, the
default precision end to end, no recompilation to switch the progress meter."""

import ast
import glob
import json
import os
import subprocess
import sys

import jax
import jax.numpy as jnp
import pytest
from helpers import as_users_run

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _imports(path: str) -> set[str]:
    tree = ast.parse(open(path).read())
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module:
            out.add(node.module)
            out |= {f"{node.module}.{a.name}" for a in node.names}
    return out


def test_the_library_never_imports_experiments_or_matplotlib_in_its_core():
    for path in glob.glob(os.path.join(ROOT, "mjx_surrogate", "**", "*.py"), recursive=True):
        mods = _imports(path)
        assert not any(m.split(".")[0] in ("experiments", "benchmarks", "configs") for m in mods), path
        if not path.endswith(("plots.py", "results.py")):
            assert not any(m.startswith("matplotlib") for m in mods), path


# The library's layers, lowest first: a module imports only from its own layer and lower
# ones. "" is the foundation: the modules at the top of the package.
LAYERS = ("", "systems", ("identification", "surrogates"), "control", "analysis", "runs")


def _rank(package: str) -> int:
    for i, layer in enumerate(LAYERS):
        if package == layer or (isinstance(layer, tuple) and package in layer):
            return i
    raise AssertionError(f"mjx_surrogate/{package}/ is in no layer of LAYERS")


def _layer_of_module(dotted: str) -> str | None:
    """ "control" for mjx_surrogate.control.ilqr, "" for mjx_surrogate.cost, None elsewhere."""
    parts = dotted.split(".")
    if parts[0] != "mjx_surrogate" or len(parts) == 1:
        return None
    return parts[1] if os.path.isdir(os.path.join(ROOT, "mjx_surrogate", parts[1])) else ""


def test_the_library_imports_only_downward():
    upward = []
    for path in glob.glob(os.path.join(ROOT, "mjx_surrogate", "**", "*.py"), recursive=True):
        rel = os.path.relpath(path, os.path.join(ROOT, "mjx_surrogate")).split(os.sep)
        if rel == ["__init__.py"]:
            continue  # the public API gathers every layer
        own = _rank(rel[0] if len(rel) > 1 else "")
        for mod in _imports(path):
            layer = _layer_of_module(mod)
            if layer is not None and _rank(layer) > own:
                upward.append(f"{'/'.join(rel)} imports {mod}")
            elif layer is not None and _rank(layer) == own and layer != (rel[0] if len(rel) > 1 else ""):
                upward.append(f"{'/'.join(rel)} imports {mod} (a sibling layer)")
    assert not upward, upward


def _module_graph(package: str) -> dict[str, set[str]]:
    """module -> the package's modules it imports: at module level, inside functions and
    under TYPE_CHECKING alike; ``from P import m`` counts as importing module P.m."""
    base = os.path.join(ROOT, package)
    paths = {}
    for path in glob.glob(os.path.join(base, "**", "*.py"), recursive=True):
        rel = os.path.relpath(path, ROOT)[:-3].replace(os.sep, ".")
        paths[rel.removesuffix(".__init__")] = path
    graph = {}
    for name, path in paths.items():
        here = name if path.endswith("__init__.py") else name.rpartition(".")[0]
        edges = set()
        for node in ast.walk(ast.parse(open(path).read())):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                parts = here.split(".")
                mod = node.module or ""
                if node.level:
                    mod = ".".join(parts[: len(parts) - node.level + 1] + ([mod] if mod else []))
                targets = [f"{mod}.{a.name}" if f"{mod}.{a.name}" in paths else mod for a in node.names]
            else:
                continue
            edges |= {t for t in targets if t in paths and t != name}
        graph[name] = edges
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_the_cycle_finder_finds_a_circle_of_local_imports():
    graph = {"p.a": {"p.b"}, "p.b": {"p.c"}, "p.c": {"p.a"}, "p.d": {"p.a"}}
    assert _cycles(graph) == [["p.a", "p.b", "p.c"]]
    assert _cycles({"p.a": {"p.b"}, "p.b": set()}) == []


@pytest.mark.parametrize("package", ["mjx_surrogate", "experiments", "benchmarks"])
def test_no_package_has_an_internal_import_cycle(package):
    graph = _module_graph(package)
    assert len(graph) > 5  # the files were read
    if package == "mjx_surrogate":
        assert sum(map(len, graph.values())) > 100  # and their imports
    assert _cycles(graph) == []


def test_no_object_of_the_package_is_written_through_its_dict():
    """Caches are explicit (``System.built``), not attributes injected into a frozen
    dataclass's ``__dict__``."""
    for path in glob.glob(os.path.join(ROOT, "mjx_surrogate", "**", "*.py"), recursive=True):
        text = open(path).read()
        assert "__dict__" not in text, path


def test_every_subpackage_is_a_layer():
    for entry in os.scandir(os.path.join(ROOT, "mjx_surrogate")):
        if entry.is_dir() and os.path.exists(os.path.join(entry.path, "__init__.py")):
            _rank(entry.name)


def test_experiment_kinds_never_import_each_other():
    for path in glob.glob(os.path.join(ROOT, "experiments", "*_study.py")):
        mods = _imports(path)
        assert not any(m.startswith("experiments") for m in mods), (path, mods)


def test_importing_the_package_changes_no_global_state_and_defers_slow_imports():
    code = """
import os, json, mujoco
env, cwd = dict(os.environ), os.getcwd()
import jax
async_before = jax.config.read("jax_cpu_enable_async_dispatch")
import mjx_surrogate, mjx_surrogate.runs.pipeline, mjx_surrogate.runs.results
import mjx_surrogate.analysis.evaluation
import mjx_surrogate.systems.backend_native, mjx_surrogate.systems.backend_mjx
import mjx_surrogate.systems.kinematics, mjx_surrogate.runs.model_defaults, experiments.run
from jax._src import xla_bridge
import sys
print(json.dumps({"env": dict(os.environ) == env, "cwd": os.getcwd() == cwd,
                  "async": jax.config.read("jax_cpu_enable_async_dispatch") == async_before,
                  "backend": bool(xla_bridge._backends),
                  "slow imports": [m for m in ("mujoco.mjx", "scipy.optimize", "scipy.stats", "trimesh")
                                   if m in sys.modules]}))
"""
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert json.loads(out.stdout.strip().splitlines()[-1]) == {
        "env": True,
        "cwd": True,
        "async": True,
        "backend": False,
        "slow imports": [],  # imported where used: 1 s of every CLI start (mujoco.mjx 0.6 s)
    }, out.stderr


@pytest.mark.slow
def test_default_precision_float32_run_end_to_end(tmp_path):
    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "experiments.run",
            "smoke_d2c",
            "--out",
            str(tmp_path),
            "--experiment.exact-oracle",
            "False",
        ],
        cwd=ROOT,
        env=as_users_run(),
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    (path,) = glob.glob(str(tmp_path / "*smoke_d2c"))
    import numpy as np

    cfg = json.load(open(os.path.join(path, "config.json")))
    metrics = json.load(open(os.path.join(path, "metrics.json")))
    arrays = np.load(os.path.join(path, "arrays.npz"))
    assert cfg["experiment"]["x64"] is False and arrays["d2c_U"].dtype == np.float32
    assert metrics["status"] == "converged"
    assert metrics["d2c"]["cost"] < 1.0 and metrics["d2c"]["goal"]["reached"]
    assert "[converged]" in out.stdout and "d2c cost" in out.stdout
    # the runtime's XLA flags, the collectives' late "may be stuck" warning among them, are
    # accepted by this jaxlib (an unknown flag aborts the process)
    flags = json.load(open(os.path.join(path, "versions.json")))["XLA_FLAGS"]
    assert "--xla_cpu_collective_call_warn_stuck_timeout_seconds=600" in flags
    assert "optimization_level" not in flags  # XLA's default code generation, not the suite's


@pytest.mark.slow
def test_switching_the_progress_meter_does_not_recompile(systems):
    from mjx_surrogate import progress
    from mjx_surrogate.control.d2c import solve_d2c
    from mjx_surrogate.control.ilqr import ILQRParams
    from mjx_surrogate.identification.sysid import SysIdParams
    from mjx_surrogate.runs.config import Config, SystemConfig, TaskConfig
    from mjx_surrogate.runs.resolution import resolve

    _, system, task = resolve(
        Config(
            system=SystemConfig(name="pendulum", backend="native"),  # MJX's step compiles 5x longer
            task=TaskConfig(preset="pendulum_d2c", T=8),
        )
    )
    U0 = jnp.zeros((task.T, 1))
    p, sid = ILQRParams(max_iter=20), SysIdParams(n_samples=6)
    # a meter passed explicitly (NO_PROGRESS or a live one) shares one program; leaving the
    # argument out compiles one without the callback at all
    quiet = solve_d2c(system, task, U0, jax.random.key(0), p, sid, progress.NO_PROGRESS)
    n = solve_d2c._cache_size()
    with progress.meter("test", 20, display=True) as meter:
        shown = solve_d2c(system, task, U0, jax.random.key(0), p, sid, meter)
    assert solve_d2c._cache_size() == n
    assert float(shown.cost) == float(quiet.cost)
