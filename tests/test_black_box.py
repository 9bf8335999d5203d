"""The black-box protocol and the execution: every kind of black box provides what the
solver needs, and where its work runs is one value of its own."""

import inspect

import jax
import numpy as np
import pytest
from jax.sharding import Mesh

from mjx_surrogate import sharding
from mjx_surrogate.errors import ConfigError
from mjx_surrogate.systems import BlackBox, Execution, burgers, from_mjcf, from_numpy, make_system, registry
from mjx_surrogate.systems.function import on_mesh

KINDS = {
    "mujoco_mjx": lambda: make_system("pendulum", backend="mjx"),
    "mujoco_native": lambda: make_system("pendulum", backend="native"),
    "jax_function": lambda: registry.make_function_system("lorenz"),
    "host_function": lambda: from_numpy(lambda x, u: x + u, 1, 1, 0.1),
    "pde": lambda: burgers.make_system(16),
}


def protocol_members(protocol) -> list[str]:
    """The attributes and methods a protocol declares (its own, not object's)."""
    declared = set(getattr(protocol, "__annotations__", {}))
    declared |= {n for n in vars(protocol) if not n.startswith("_")}
    return sorted(declared)


def provides(obj, name: str) -> bool:
    """Whether ``obj`` has ``name`` without running a property (some build programs)."""
    try:
        inspect.getattr_static(obj, name)
        return True
    except AttributeError:
        return False


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_every_kind_of_black_box_provides_the_protocol(kind):
    box = KINDS[kind]()
    members = protocol_members(BlackBox)
    assert {"execution", "step", "mj_model", "exact_step", "on_one_device"} <= set(members)
    assert [m for m in members if not provides(box, m)] == []
    assert isinstance(box.execution, Execution)
    assert (box.backend, box.mesh) == (box.execution.backend, box.execution.mesh)
    assert box.compiler_options == box.execution.compiler_options
    one = box.on_one_device()
    assert one.mesh is None and (one.nx, one.nu, one.dt) == (box.nx, box.nu, box.dt)


def test_an_execution_is_a_value_checked_where_it_is_made():
    assert Execution("native", 2) == Execution("native", 2)
    assert hash(Execution("native", 2)) == hash(Execution("native", 2))
    assert Execution("native", 2) != Execution("native", 1)
    assert [Execution(b).on_host for b in ("mjx", "native", "jax", "host")] == [False, True, False, True]
    assert Execution("mjx").compiler_options is None and Execution("jax").compiler_options is None
    with pytest.raises(ConfigError, match=r"^system.backend: unknown backend 'gpu'; valid: "):
        Execution("gpu")
    with pytest.raises(ConfigError, match="system.native_threads"):
        Execution("native", 0)


def test_a_host_step_is_spread_over_one_device_per_process():
    """A traced step takes the whole mesh; a host call runs on the first device of each
    process (:func:`sharding.one_device_per_process`), here the only one, so none."""
    mesh = Mesh(np.asarray(jax.devices()), (sharding.AXIS,))
    assert Execution("jax").over(mesh).mesh is mesh and Execution("mjx").over(mesh).mesh is mesh
    assert Execution("host").over(mesh).mesh is None and Execution("native", 2).over(mesh).mesh is None
    host = from_numpy(lambda x, u: x + u, 1, 1, 0.1)
    assert on_mesh(host, mesh).mesh is None
    jax_fn = registry.make_function_system("lorenz")
    spread = on_mesh(jax_fn, mesh)
    assert spread.mesh is mesh and spread.on_one_device().mesh is None


def test_systems_by_content_are_kept_per_execution(tmp_path):
    """The cache of systems keys on the execution: other threads, another system."""
    path = tmp_path / "arm.xml"
    path.write_text(
        "<mujoco><worldbody><body><joint name='j' type='hinge'/><geom size='0.1'/></body>"
        "</worldbody><actuator><motor joint='j'/></actuator></mujoco>"
    )
    one = from_mjcf(str(path), backend="native", native_threads=1)
    assert from_mjcf(str(path), backend="native", native_threads=1) is one
    two = from_mjcf(str(path), backend="native", native_threads=2)
    assert two is not one and two.execution == Execution("native", 2)
    assert one.execution == Execution("native", 1) and one.native.nthread == 1
