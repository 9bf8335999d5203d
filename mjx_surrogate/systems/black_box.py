"""What the solver, the identification schemes, the planners and the evaluation need of a
black box, declared once. A MuJoCo model (:class:`~.system.System`) and a step function
(:class:`~.function.FunctionSystem`) both provide it; a new kind of black box provides it
too, or is built as one of them (docs/extending.md, "A kind of black box")."""

from __future__ import annotations

from typing import Callable, Protocol, runtime_checkable

import jax
import mujoco
from jax.sharding import Mesh

from mjx_surrogate.systems.execution import Execution

StepFn = Callable[[jax.Array, jax.Array], jax.Array]


@runtime_checkable
class BlackBox(Protocol):
    """A discrete-time black box x_{t+1} = f(x_t, u_t) with its execution.

    Black boxes hash by identity, so that one can be a static argument of ``jax.jit``.

    Attributes:
      name: the name a config gives it (``system.name``).
      nx, nu: state and control sizes; dt: the control period in seconds.
      step: jittable ``(x [nx], u [nu]) -> x_next [nx]``.
      rollout: jittable ``(x0 [B, nx], U [B, T, nu]) -> X [B, T+1, nx]``.
      closed_loop: the line search's closed-loop rollouts of all step sizes in one call
        (``ilqr.ClosedLoopFn``), or None (the line search vmaps ``step``).
      execution: backend, host threads and devices (:class:`~.execution.Execution`).
      mj_model: the MuJoCo model, or None: the capability of a MuJoCo black box (actuator
        limits, the "hold" start, body-named plant changes, keyframes, rendering).
      exact_step: the differentiable step the exact oracle iterates on, or None: a black
        box without derivatives, judged against central differences of its own step.
      state_labels [nx], control_labels [nu]: coordinate names for tables and figures.
      angle_pairs: (angle, angular rate) state index pairs (SINDy's sin/cos coordinates).
    """

    name: str
    step: StepFn
    rollout: Callable[[jax.Array, jax.Array], jax.Array]
    closed_loop: Callable | None
    execution: Execution

    @property
    def nx(self) -> int: ...

    @property
    def nu(self) -> int: ...

    @property
    def dt(self) -> float: ...

    @property
    def mj_model(self) -> mujoco.MjModel | None: ...

    @property
    def exact_step(self) -> StepFn | None: ...

    @property
    def exact_jacobians_batch(self) -> Callable:
        """(X [B, nx], U [B, nu]) -> (A [B, nx, nx], B [B, nx, nu]): the exact oracle."""
        ...

    @property
    def state_labels(self) -> tuple[str, ...]: ...

    @property
    def control_labels(self) -> tuple[str, ...]: ...

    @property
    def angle_pairs(self) -> tuple[tuple[int, int], ...]: ...

    @property
    def backend(self) -> str:
        """``execution.backend``."""
        ...

    @property
    def mesh(self) -> Mesh | None:
        """``execution.mesh``."""
        ...

    @property
    def compiler_options(self) -> dict | None:
        """``execution.compiler_options``."""
        ...

    def on_one_device(self) -> BlackBox:
        """The same black box with its batched work kept on one device."""
        ...
