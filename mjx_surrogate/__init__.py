"""mjx_surrogate: batched data-driven nonlinear optimal control on MuJoCo with JAX."""

from mjx_surrogate import _xla_flags  # noqa: F401  (must run before jax initialises)

__version__ = "0.1.0"
