"""Black boxes that are not MuJoCo files: a JAX function, or a host (NumPy) function.

What the solver, the identification schemes and the evaluation use of a system is small
(:class:`~.black_box.BlackBox`); a :class:`FunctionSystem` provides it around a user's
function. The exact oracle is ``jax.jacfwd`` through a JAX step
(``exact_jacobians_batch``), while a host function has none and is judged against central
differences of its own step (``experiment.oracle = "finite_difference"``).

A host function is called through ``jax.pure_callback`` with ``vmap_method =
"broadcast_all"``: one call per batch (the identification's thousands of samples, the
line search's step sizes), on the host. Its contract: ``fn(x [nx], u [nu]) -> x_next
[nx]``, or with ``vectorized=True`` ``fn(X [N, nx], U [N, nu]) -> X_next [N, nx]``; a
result of the wrong shape raises ValueError naming the function; a non-finite result is
passed on and ends a solve ``diverged``, as a MuJoCo instability does.
"""

from __future__ import annotations

import dataclasses
from concurrent.futures import ThreadPoolExecutor
from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh

from mjx_surrogate.errors import ConfigError
from mjx_surrogate.systems.execution import Execution, OnExecution

StepFn = Callable[[jax.Array, jax.Array], jax.Array]


@dataclasses.dataclass(frozen=True, eq=False)
class FunctionSystem(OnExecution):
    """A black box x_{t+1} = step(x_t, u_t) given as a function. Hashes by identity, so it
    can be a static argument of ``jax.jit``.

    execution: its backend, "jax" (a traceable step, differentiable unless ``exact_step``
    is None) or "host" (a host function behind a callback), and its devices. u_min,
    u_max [nu]: the controls' limits (+-inf where unbounded), which a task takes unless
    it narrows them. angle_pairs: (angle, angular rate) state indices, the default
    sin/cos coordinates of a SINDy library (a MuJoCo system's hinge joints)."""

    name: str
    nx: int
    nu: int
    dt: float
    step: StepFn
    rollout: Callable[[jax.Array, jax.Array], jax.Array]
    execution: Execution
    state_labels: tuple[str, ...]
    control_labels: tuple[str, ...]
    u_min: tuple[float, ...]
    u_max: tuple[float, ...]
    exact_step: StepFn | None = None
    closed_loop: Callable | None = None
    angle_pairs: tuple[tuple[int, int], ...] = ()
    source: str | None = None  # the file that defines it, recorded by a run folder

    mj_model = None  # not a MuJoCo model: nothing runs ``mujoco`` for it

    @property
    def nq(self) -> int:
        """Every coordinate counts as a position (plots show the first ones)."""
        return self.nx

    @property
    def nv(self) -> int:
        return 0

    def on_one_device(self) -> "FunctionSystem":
        if self.mesh is None:
            return self
        return dataclasses.replace(self, execution=self.execution.on_one_device())

    @property
    def exact_jacobians_batch(self) -> Callable[[jax.Array, jax.Array], tuple[jax.Array, jax.Array]]:
        """(X [B, nx], U [B, nu]) -> (A [B, nx, nx], B [B, nx, nu]) by ``jax.jacfwd``."""
        if self.exact_step is None:
            raise ConfigError(
                "experiment.oracle",
                f"system {self.name!r} is a {self.backend} function without derivatives; "
                "valid: finite_difference",
            )
        return jax.vmap(jax.jacfwd(self.exact_step, argnums=(0, 1)))

    def __repr__(self) -> str:
        sizes = f"nx={self.nx}, nu={self.nu}, dt={self.dt:g}"
        return f"FunctionSystem({self.name!r}, backend={self.backend!r}, {sizes})"


def scan_rollout(step: StepFn) -> Callable[[jax.Array, jax.Array], jax.Array]:
    """rollout(x0 [B, nx], U [B, T, nu]) -> X [B, T+1, nx] by a scan of ``step``."""

    def one(x0, U):
        def body(x, u):
            nxt = step(x, u)
            return nxt, nxt

        _, X = jax.lax.scan(body, x0, U)
        return jnp.concatenate([x0[None], X])

    return jax.vmap(one)


def _labels(labels, n: int, prefix: str) -> tuple[str, ...]:
    labels = tuple(labels) if labels is not None else tuple(f"{prefix}{i}" for i in range(n))
    if len(labels) != n:
        raise ConfigError("system.labels", f"{len(labels)} {prefix} labels for {n} coordinates")
    return labels


def _system(name, nx, nu, dt, step, backend, u_min, u_max, state_labels, control_labels, exact_step, angles):
    """A :class:`FunctionSystem` with its sizes, limits, labels and angles checked."""
    lo, hi = _limits(u_min, u_max, nu)
    labels = _labels(state_labels, nx, "x"), _labels(control_labels, nu, "u")
    pairs = tuple((int(a), int(b)) for a, b in angles)
    if any(not (0 <= i < nx) for pair in pairs for i in pair):
        raise ConfigError("system.angle_pairs", f"state indices must be in [0, {nx}), got {pairs}")
    return FunctionSystem(
        name,
        int(nx),
        int(nu),
        float(dt),
        step,
        scan_rollout(step),
        Execution(backend),
        *labels,
        lo,
        hi,
        exact_step,
        angle_pairs=pairs,
    )


def _limits(lo, hi, nu: int) -> tuple[tuple[float, ...], tuple[float, ...]]:
    lo = np.full(nu, -np.inf) if lo is None else np.broadcast_to(np.asarray(lo, float), (nu,))
    hi = np.full(nu, np.inf) if hi is None else np.broadcast_to(np.asarray(hi, float), (nu,))
    if not np.all(lo < hi):
        raise ConfigError("system.u_min", f"control limits need u_min < u_max, got {lo} and {hi}")
    return tuple(float(v) for v in lo), tuple(float(v) for v in hi)


def from_jax(
    step: StepFn,
    nx: int,
    nu: int,
    dt: float,
    *,
    name: str = "jax_function",
    u_min=None,
    u_max=None,
    state_labels=None,
    control_labels=None,
    angle_pairs=(),
    differentiable: bool = True,
) -> FunctionSystem:
    """A black box from a traceable ``step(x [nx], u [nu]) -> x_next [nx]``; its oracle is
    ``jax.jacfwd`` through ``step`` unless ``differentiable`` is False. angle_pairs:
    (angle, rate) state index pairs, the default sin/cos coordinates of SINDy libraries."""
    exact = step if differentiable else None
    labels = state_labels, control_labels
    return _system(name, nx, nu, dt, step, "jax", u_min, u_max, *labels, exact, angle_pairs)


def host_step(
    fn: Callable, nx: int, nu: int, *, vectorized: bool = False, threads: int = 1, name: str = "step"
) -> StepFn:
    """A traceable step that calls ``fn`` on the host (module docstring), once per batch;
    per-sample functions run over the batch in ``threads`` threads (1: a plain loop)."""
    pool = ThreadPoolExecutor(threads) if threads > 1 else None

    def on_host(x: np.ndarray, u: np.ndarray) -> np.ndarray:
        lead = x.shape[:-1]
        xb, ub = np.asarray(x).reshape(-1, nx), np.asarray(u).reshape(-1, nu)
        if vectorized:
            out = np.asarray(fn(xb, ub), dtype=float)
        else:
            rows = pool.map(fn, xb, ub) if pool is not None else map(fn, xb, ub)
            out = np.asarray([np.asarray(r, dtype=float).reshape(-1) for r in rows])
        if out.shape != (xb.shape[0], nx):
            got = out.shape if vectorized else out.shape[1:]
            want = (xb.shape[0], nx) if vectorized else (nx,)
            raise ValueError(f"{name} returned shape {got}, expected {want}")
        return out.reshape(lead + (nx,)).astype(x.dtype)

    def step(x: jax.Array, u: jax.Array) -> jax.Array:
        out = jax.ShapeDtypeStruct(x.shape, x.dtype)
        return jax.pure_callback(on_host, out, x, u, vmap_method="broadcast_all")

    return step


def on_mesh(system: FunctionSystem, mesh: Mesh | None) -> FunctionSystem:
    """``system`` with its batched work spread over ``mesh`` (None: as it is): a JAX
    function over every device of the mesh, a host function on one device per process
    (as native MuJoCo)."""
    if mesh is None:
        return system
    return dataclasses.replace(system, execution=system.execution.over(mesh))


def from_numpy(
    fn: Callable,
    nx: int,
    nu: int,
    dt: float,
    *,
    name: str = "host_function",
    vectorized: bool = False,
    threads: int = 1,
    u_min=None,
    u_max=None,
    state_labels=None,
    control_labels=None,
    angle_pairs=(),
) -> FunctionSystem:
    """A black box from a host function (NumPy, a C extension, another simulator in this
    process): ``fn(x [nx], u [nu]) -> x_next [nx]`` (``vectorized``: [N, nx], [N, nu] ->
    [N, nx]). No derivatives: its oracle is central differences of its step. angle_pairs
    as for :func:`from_jax`."""
    _limits(u_min, u_max, nu)  # checked before the step is built
    step = host_step(fn, nx, nu, vectorized=vectorized, threads=threads, name=name)
    labels = state_labels, control_labels
    return _system(name, nx, nu, dt, step, "host", u_min, u_max, *labels, None, angle_pairs)


def rk4(vector_field: Callable[[jax.Array, jax.Array], jax.Array], dt: float, substeps: int) -> StepFn:
    """The step x_{t+1} = Phi_dt(x_t; u_t) of an ODE dx/dt = f(x, u) with u held over the
    control period dt: ``substeps`` classical Runge-Kutta steps of dt / substeps."""
    h = dt / substeps

    def step(x, u):
        def one(x, _):
            k1 = vector_field(x, u)
            k2 = vector_field(x + 0.5 * h * k1, u)
            k3 = vector_field(x + 0.5 * h * k2, u)
            k4 = vector_field(x + h * k3, u)
            return x + (h / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4), None

        return jax.lax.scan(one, x, None, length=substeps)[0]

    return step
