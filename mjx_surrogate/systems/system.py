"""The black-box system interface shared by both simulator backends."""

from __future__ import annotations

import collections
import dataclasses
import hashlib
import os
from typing import Callable

import jax
import mujoco
import numpy as np
from jax.sharding import Mesh

from mjx_surrogate.errors import ConfigError
from mjx_surrogate.systems import backend_mjx, backend_native, exported_step
from mjx_surrogate.systems.execution import Execution, OnExecution

BACKENDS = ("mjx", "native")


@dataclasses.dataclass(frozen=True, eq=False)
class System(OnExecution):
    """A MuJoCo model seen as a discrete-time map x_{t+1} = f(x_t, u_t).

    x = [qpos, qvel, act] (nx = nq + nv + na), u = ctrl (nu), one control step is
    ``substeps`` physics steps of ``mj_model.opt.timestep``. Hashes by identity, so it
    can be a static argument of ``jax.jit``.

    Attributes:
      step: jittable ``(x[nx], u[nu]) -> x_next[nx]`` on the execution's backend.
      rollout: jittable ``(x0[B, nx], U[B, T, nu]) -> X[B, T+1, nx]``.
      closed_loop: the iLQR line search's closed-loop rollouts for all step sizes in one
        call (native backend: one host call instead of one per time step), or None.
      execution: the backend ("mjx" | "native"), the native pool's threads and the devices
        that batched work is spread over (:class:`~.execution.Execution`).
      built: what the system builds once, on first use, by name (the native simulator, the
        MJX physics and the oracle's exported programs, the joint limits, point-goal
        functions per goal set): an explicit cache of this object, never compared or hashed.
    """

    name: str
    xml: str
    mj_model: mujoco.MjModel
    substeps: int
    step: Callable[[jax.Array, jax.Array], jax.Array]
    rollout: Callable[[jax.Array, jax.Array], jax.Array]
    execution: Execution
    closed_loop: Callable | None = None  # batched line-search rollout (ilqr.ClosedLoopFn)
    built: dict = dataclasses.field(default_factory=dict, repr=False, compare=False)

    def once(self, name: str, build: Callable[[], object]):
        """``built[name]``, made by ``build()`` the first time it is asked for."""
        if name not in self.built:
            self.built[name] = build()
        return self.built[name]

    @property
    def nq(self) -> int:
        return self.mj_model.nq

    @property
    def nv(self) -> int:
        return self.mj_model.nv

    @property
    def nu(self) -> int:
        return self.mj_model.nu

    @property
    def nx(self) -> int:
        return self.mj_model.nq + self.mj_model.nv + self.mj_model.na

    @property
    def dt(self) -> float:
        """Control time step in seconds."""
        return float(self.mj_model.opt.timestep) * self.substeps

    @property
    def state_labels(self) -> tuple[str, ...]:
        """Names of the state coordinates [qpos, qvel, act] from the model's joints."""
        return tuple(state_labels(self.mj_model))

    @property
    def control_labels(self) -> tuple[str, ...]:
        m = self.mj_model
        return tuple(mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, i) or f"u{i}" for i in range(m.nu))

    @property
    def angle_pairs(self) -> tuple[tuple[int, int], ...]:
        """(angle, angular velocity) state indices of every hinge joint."""
        return tuple(hinge_state_indices(self.mj_model))

    @property
    def state_limits(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(lower [nx], upper [nx]): the range of each limited hinge or slide joint's qpos,
        -inf / +inf elsewhere; None if the model limits no such joint. At a limit the
        one-step map has a kink (the limit's constraint switches on)."""
        return self.once("state_limits", lambda: joint_limits(self.mj_model))

    @property
    def mjx_step(self):
        """Differentiable MJX step (the exact-Jacobian oracle), whatever the backend; on one
        device its calls and vmaps run exported programs (:mod:`exported_step`), so that a
        native system's oracle is not traced again by later runs."""
        physics = lambda: self._mjx_physics  # noqa: E731
        return self.once(
            "mjx_step", lambda: self._exported(lambda: physics().step, lambda: physics().step_batch, "step")
        )

    @property
    def _mjx_physics(self) -> backend_mjx.MjxPhysics:
        """The MJX step, its batch and its Jacobians, built on first use."""
        return self.once("mjx_physics", lambda: backend_mjx.make_mjx_physics(self.mj_model, self.substeps))

    @property
    def native(self) -> backend_native.NativeSimulator:
        """Host-side native simulator (replay, references), whatever the backend."""
        return self.once(
            "native",
            lambda: backend_native.NativeSimulator(self.mj_model, self.substeps, self.execution.threads),
        )

    @property
    def mjx_jacobians(self):
        """``(x[nx], u[nu]) -> (A [nx, nx], B [nx, nu])``, the exact oracle's Jacobians
        (:attr:`backend_mjx.MjxPhysics.jacobians_batch`), exported as :attr:`mjx_step` is."""

        def one(x, u):
            A, B = self._mjx_physics.jacobians_batch(x[None], u[None])
            return A[0], B[0]

        return self.once(
            "mjx_jacobians",
            lambda: self._exported(lambda: one, lambda: self._mjx_physics.jacobians_batch, "jacobians"),
        )

    @property
    def mjx_jacobians_batch(self):
        """``(X [B, nx], U [B, nu]) -> (A [B, nx, nx], B [B, nx, nu])``: :attr:`mjx_jacobians`
        over a batch. On one device only the batch's program is exported or loaded (a
        ``vmap`` of the per-point function exports the unbatched one too)."""
        return getattr(self.mjx_jacobians, "batched", None) or self._mjx_physics.jacobians_batch

    @property
    def exact_step(self):
        """The differentiable step the exact oracle iterates on: the black box's own on MJX,
        the MJX physics of the same model on the native backend."""
        return self.step if self.backend == "mjx" else self.mjx_step

    @property
    def exact_jacobians_batch(self):
        """The exact oracle's batched Jacobians (:attr:`mjx_jacobians_batch`)."""
        return self.mjx_jacobians_batch

    def _exported(self, build, build_batch, tag: str):
        """``build()`` (its batches: ``build_batch()``) on one device as exported programs,
        built only to be exported or differentiated; over a mesh traced as they are."""
        if self.mesh is not None:
            return exported_step.with_batch_rule(build(), build(), build_batch())
        lazy, lazy_batch = exported_step.lazily(build), exported_step.lazily(build_batch)
        return exported_step.with_exported_batches(lazy, self.mj_model, self.substeps, tag, lazy_batch)

    def on_one_device(self) -> "System":
        """The same system with its batched work kept on one device (for use inside a
        computation that is itself spread over the mesh, e.g. one of many solves)."""
        if self.mesh is None:
            return self
        shared = ("native", "mjx_step", "mjx_jacobians", "mjx_physics")  # what it built so far
        kept = {k: v for k, v in self.built.items() if k in shared}
        return dataclasses.replace(self, execution=self.execution.on_one_device(), built=kept)

    def __repr__(self) -> str:
        return (
            f"System({self.name!r}, backend={self.backend!r}, nx={self.nx}, nu={self.nu}, "
            f"substeps={self.substeps}, dt={self.dt:g})"
        )


def joint_limits(m: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray] | None:
    """:attr:`System.state_limits` of model ``m``."""
    nx = m.nq + m.nv + m.na
    lo, hi = np.full(nx, -np.inf), np.full(nx, np.inf)
    kinds = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
    limited = [j for j in range(m.njnt) if m.jnt_limited[j] and int(m.jnt_type[j]) in kinds]
    for j in limited:
        a = m.jnt_qposadr[j]
        lo[a], hi[a] = m.jnt_range[j] + np.array([1.0, -1.0]) * m.jnt_margin[j]  # active inside the margin
    return (lo, hi) if limited else None


def can_have_constraints(m: mujoco.MjModel) -> bool:
    """Whether any constraint (contact, limit, equality, friction loss) can ever be active."""
    contacts = m.npair > 0 or (m.geom_contype.any() and m.geom_conaffinity.any())
    limits = bool(m.jnt_limited.any()) or bool(m.tendon_limited.any())
    friction = bool((m.dof_frictionloss > 0).any()) or bool((m.tendon_frictionloss > 0).any())
    return bool(contacts or limits or friction or m.neq > 0)


def compile_mjcf(
    xml: str | None,
    field: str = "system.mjcf",
    timestep: float | None = None,
    path: str | None = None,
    need_controls: bool = True,
) -> tuple[mujoco.MjModel, str]:
    """Compile MJCF text (or the file at ``path``, its includes and assets resolved next to
    it), disabling the constraint solver where nothing can be constrained. A model without
    actuators is refused unless ``need_controls`` is false (``inspect`` describes any model).

    Returns the model and the exact MJCF that was compiled (after the option changes). A
    ``path`` ending in ``.mjb`` is a compiled model as a run folder keeps it
    (``model.mjb``: meshes included), loaded as it is; its MJCF text is "".
    """
    if path is not None and path.endswith(".mjb"):
        try:
            model = mujoco.MjModel.from_binary_path(path)
        except Exception as exc:
            raise ConfigError(field, f"invalid MJB file ({' '.join(str(exc).split())})") from None
        if timestep is not None:
            model.opt.timestep = timestep
        return model, ""
    try:
        spec = mujoco.MjSpec.from_file(path) if path is not None else mujoco.MjSpec.from_string(xml)
        if timestep is not None:
            spec.option.timestep = timestep
        model = spec.compile()
    except Exception as exc:  # mujoco raises ValueError with a multi-line message
        msg = " ".join(str(exc).split())
        raise ConfigError(field, f"invalid MJCF ({msg})") from None
    if model.nu == 0 and need_controls:
        mocap = " (its mocap bodies are positioned by the user, not by controls)" if model.nmocap else ""
        raise ConfigError(field, f"the model has no actuators{mocap}; at least one control is needed")
    if not can_have_constraints(model):
        spec.option.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
        model = spec.compile()
    return model, spec.to_xml()


def build_system(
    name: str,
    xml: str | None,
    substeps: int,
    backend: str,
    timestep: float | None = None,
    native_threads: int | None = None,
    field: str = "system.mjcf",
    path: str | None = None,
    mesh: Mesh | None = None,
) -> System:
    """Compile ``xml`` (or the MJCF file at ``path``) and wrap it as a :class:`System` on
    ``backend`` ("mjx" | "native"), its batched work spread over ``mesh``."""
    if backend not in BACKENDS:
        raise ConfigError("system.backend", f"unknown backend {backend!r}; valid: {BACKENDS}")
    if not isinstance(substeps, int) or substeps < 1:
        raise ConfigError("system.substeps", f"must be a positive integer, got {substeps!r}")
    model, exact_xml = compile_mjcf(xml, field, timestep, path)
    execution = Execution(backend, native_threads or os.cpu_count() or 1).over(mesh)
    x64 = bool(jax.config.jax_enable_x64)
    key = (name, model_digest(model), exact_xml, substeps, execution, x64)
    if key in _BUILT:  # the same model as built before: its System, and every program jitted on it
        _BUILT.move_to_end(key)
        return _BUILT[key]
    system = _build(name, model, exact_xml, substeps, execution)
    _BUILT[key] = system
    while len(_BUILT) > _KEEP:
        _BUILT.popitem(last=False)
    return system


# Systems by content: (name, model digest, MJCF, substeps, execution, x64) -> System,
# the _KEEP most recently asked for. A System hashes by identity (a static argument of
# jax.jit), so building the same model again would compile every program again.
_BUILT: "collections.OrderedDict[tuple, System]" = collections.OrderedDict()
_KEEP = 32


def forget_systems() -> None:
    """Empty the cache of systems by content, as a new process starts with none."""
    _BUILT.clear()


def model_digest(model: mujoco.MjModel) -> str:
    """sha256 of the compiled model (``mj_saveModel``): equal for equal models, whatever
    file, includes or assets they were compiled from."""
    buf = np.zeros(mujoco.mj_sizeModel(model), np.uint8)
    mujoco.mj_saveModel(model, None, buf)
    return hashlib.sha256(buf.tobytes()).hexdigest()


def _build(name, model, exact_xml, substeps, execution: Execution) -> System:
    """The :class:`System` of a compiled model on ``execution``."""
    mesh = execution.mesh
    if execution.backend == "mjx":
        physics = backend_mjx.make_mjx_physics(model, substeps)
        plain = physics.step
        # Programs exported for one device; work spread over a mesh traces the step and its
        # batch (exports for one device conflicted with the sharded programs).
        if mesh is None:
            step = exported_step.with_exported_batches(plain, model, substeps, batch=physics.step_batch)
        else:
            step = exported_step.with_batch_rule(plain, plain, physics.step_batch)
        rollout = backend_mjx.make_mjx_rollout(step)
    else:
        sim = backend_native.NativeSimulator(model, substeps, execution.threads)
        step = backend_native.make_native_step(sim)
        rollout = backend_native.make_native_rollout(sim)
    if execution.backend == "native":
        closed = backend_native.make_native_closed_loop(sim)
        built = {"native": sim}  # one pool
    else:  # the step's own physics: differentiable, the same numbers as step, its Jacobians
        closed, built = None, {"mjx_step": plain, "mjx_physics": physics}
    return System(name, exact_xml, model, substeps, step, rollout, execution, closed, built)


def hinge_state_indices(m: mujoco.MjModel) -> list[tuple[int, int]]:
    """(angle, angular velocity) state indices of every hinge joint, in joint order."""
    return [
        (int(m.jnt_qposadr[j]), m.nq + int(m.jnt_dofadr[j]))
        for j in range(m.njnt)
        if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE
    ]


def state_labels(m: mujoco.MjModel) -> list[str]:
    """Names of the nx state coordinates [qpos, qvel, act] from the model's joints."""
    qpos, qvel = [], []
    for j in range(m.njnt):
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) or f"joint{j}"
        kind = m.jnt_type[j]
        if kind == mujoco.mjtJoint.mjJNT_FREE:
            qpos += [f"{name}.{c}" for c in ("x", "y", "z", "qw", "qx", "qy", "qz")]
            qvel += [f"{name}.{c}" for c in ("vx", "vy", "vz", "wx", "wy", "wz")]
        elif kind == mujoco.mjtJoint.mjJNT_BALL:
            qpos += [f"{name}.{c}" for c in ("qw", "qx", "qy", "qz")]
            qvel += [f"{name}.{c}" for c in ("wx", "wy", "wz")]
        else:
            qpos.append(name)
            qvel.append(f"d{name}")
    return qpos + qvel + [f"act{i}" for i in range(m.na)]


def actuated_state_indices(m: mujoco.MjModel) -> list[int]:
    """qpos indices of the hinge and slide joints that actuators drive (directly or through
    a tendon), in state order; all hinge and slide joints if none is found."""
    joints = set()
    for a in range(m.nu):
        kind, target = int(m.actuator_trntype[a]), int(m.actuator_trnid[a, 0])
        if kind in (int(mujoco.mjtTrn.mjTRN_JOINT), int(mujoco.mjtTrn.mjTRN_JOINTINPARENT)):
            joints.add(target)
        elif kind == int(mujoco.mjtTrn.mjTRN_TENDON):
            adr, num = m.tendon_adr[target], m.tendon_num[target]
            for w in range(adr, adr + num):
                if int(m.wrap_type[w]) == int(mujoco.mjtWrap.mjWRAP_JOINT):
                    joints.add(int(m.wrap_objid[w]))
    scalar = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
    chosen = [j for j in sorted(joints) if int(m.jnt_type[j]) in scalar]
    if not chosen:
        chosen = [j for j in range(m.njnt) if int(m.jnt_type[j]) in scalar]
    return sorted(int(m.jnt_qposadr[j]) for j in chosen)
