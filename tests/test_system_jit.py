"""system_jit: one jax.jit per set of a system's XLA options, called and lowered as a jit."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from mjx_surrogate.systems.system_jit import system_jit


@dataclasses.dataclass(frozen=True)
class Box:
    scale: float
    level: int | None = None

    @property
    def compiler_options(self):
        return None if self.level is None else {"xla_backend_optimization_level": self.level}


def test_each_options_set_has_its_own_jit_and_values_do_not_recompile():
    traced = []

    @system_jit(static_argnames=("system",))
    def f(system, x):
        traced.append(system)
        return system.scale * jnp.sin(x)

    x = jnp.linspace(0.0, 1.0, 5)
    default, level1 = Box(2.0), Box(2.0, level=1)
    np.testing.assert_allclose(f(default, x), 2.0 * np.sin(np.asarray(x)), rtol=1e-12)
    np.testing.assert_allclose(f(level1, x), 2.0 * np.sin(np.asarray(x)), rtol=1e-12)
    assert len(f._jits) == 2 and f._cache_size() == 2
    f(default, x + 1.0), f(level1, x + 1.0)  # new values
    assert f._cache_size() == 2 and len(traced) == 2
    lowered = f.lower(level1, x)
    assert isinstance(lowered, jax.stages.Lowered)
    np.testing.assert_array_equal(lowered.compile()(x), f(level1, x))


def test_a_system_without_compiler_options_gets_xlas_defaults():
    @dataclasses.dataclass(frozen=True)
    class Bare:
        scale: float

    f = system_jit(static_argnames=("system",))(lambda system, x: system.scale * x)
    assert float(f(Bare(3.0), jnp.asarray(2.0))) == 6.0 and list(f._jits) == [()]
