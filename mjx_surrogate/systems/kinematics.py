"""Positions of named sites and bodies as a differentiable function of the state.

Task costs on points (a fingertip at a target, a nose, an end effector) need p(x) and its
Jacobian. Two sources, the same numbers: MJX forward kinematics on the same model
(traced, autodiff gives the Jacobian), or native ``mj_kinematics`` called from inside the
trace (``native_points_fn``, a named host call: every model MuJoCo loads; the Jacobian
by central differences in qpos, exact to round-off for the smooth kinematic map). The
dynamics are never differentiated here.
"""

from __future__ import annotations

import contextlib
import copy
import queue

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from mjx_surrogate.errors import ConfigError
from mjx_surrogate.systems import host_call
from mjx_surrogate.systems.backend_mjx import import_mjx
from mjx_surrogate.systems.backend_native import model_key

_KINDS = {"site": mujoco.mjtObj.mjOBJ_SITE, "body": mujoco.mjtObj.mjOBJ_BODY}


def object_names(m: mujoco.MjModel, kind: str) -> list[str]:
    count = m.nsite if kind == "site" else m.nbody
    return [mujoco.mj_id2name(m, _KINDS[kind], i) or f"#{i}" for i in range(count)]


def point_ids(m: mujoco.MjModel, goals, field: str = "task.goals") -> list[tuple[str, int]]:
    """[(kind, id)] of goals with ``.kind`` and ``.name``; unknown names name the field."""
    out = []
    for i, g in enumerate(goals):
        j = mujoco.mj_name2id(m, _KINDS[g.kind], g.name)
        if j < 0:
            valid = ", ".join(n for n in object_names(m, g.kind) if not n.startswith("#")) or "none"
            raise ConfigError(
                f"{field}[{i}].name", f"no {g.kind} named {g.name!r}; the model's {g.kind}s: {valid}"
            )
        out.append((g.kind, j))
    return out


def make_points_fn(m: mujoco.MjModel, ids: list[tuple[str, int]], field: str = "task.goals"):
    """``points(x [nx]) -> [k, 3]`` world positions of the (kind, id) points at qpos = x[:nq]."""
    mjx = import_mjx()
    try:
        with jax.ensure_compile_time_eval():
            device = jax.local_devices()[0]
            model = mjx.put_model(m, device=device)
            data0 = mjx.make_data(model, device=device)
    except Exception as exc:  # a feature MJX lacks
        raise ConfigError(field, f"point goals need MJX kinematics, which this model lacks ({exc})") from None
    nq = m.nq

    def points(x: jax.Array) -> jax.Array:
        d = mjx.kinematics(model, data0.replace(qpos=x[:nq].astype(data0.qpos.dtype)))
        rows = [d.site_xpos[j] if k == "site" else d.xpos[j] for k, j in ids]  # k goals, static
        return jnp.stack(rows).astype(x.dtype)

    return points


def native_points_fn(m: mujoco.MjModel, ids: list[tuple[str, int]]):
    """``points(x [nx]) -> [k, 3]`` as :func:`make_points_fn`, by native ``mj_kinematics``
    through a named host call (:mod:`~mjx_surrogate.systems.host_call`, batched over any
    leading axes), with a custom JVP whose Jacobian [k, 3, nx] (zero beyond qpos) is
    MuJoCo's own (``mj_jacSite``, ``mj_jacBody``) where every joint is a hinge or a slide,
    else central differences in qpos (a quaternion's four coordinates)."""
    m = copy.copy(m)  # the key is its content: a later edit of the caller's model is not seen
    nq, k = m.nq, len(ids)
    key = model_key(m, "points", [(kind, int(j)) for kind, j in ids])
    h = 1e-6
    hinges_and_slides = m.nq == m.nv  # no ball or free joint: no quaternion in qpos
    free: queue.SimpleQueue = queue.SimpleQueue()  # MjData reused across calls

    @contextlib.contextmanager
    def own_data():
        """A free MjData (a new one when none is: callbacks of several devices may run at once)."""
        try:
            data = free.get_nowait()
        except queue.Empty:
            data = mujoco.MjData(m)
        try:
            yield data
        finally:
            free.put(data)

    def at(q: np.ndarray, data: mujoco.MjData) -> np.ndarray:
        data.qpos[:] = q
        mujoco.mj_kinematics(m, data)
        return np.stack([data.site_xpos[j] if kind == "site" else data.xpos[j] for kind, j in ids])

    def host_points(x: np.ndarray) -> np.ndarray:
        x = np.asarray(x)
        flat = x.reshape(-1, x.shape[-1]).astype(np.float64)
        with own_data() as data:
            out = np.stack([at(row[:nq], data) for row in flat])
        return out.reshape(x.shape[:-1] + (k, 3)).astype(x.dtype)

    def jacobian_rows(flat: np.ndarray, J: np.ndarray, data: mujoco.MjData) -> None:
        """J [B, k, 3, nx] of the rows flat [B, nx], written in place."""
        if hinges_and_slides:  # qvel is the rate of qpos: MuJoCo's own point Jacobians
            jac = np.empty((3, m.nv))
            for b, row in enumerate(flat):
                data.qpos[:] = row[:nq]
                mujoco.mj_kinematics(m, data)
                mujoco.mj_comPos(m, data)
                for i, (kind, j) in enumerate(ids):
                    (mujoco.mj_jacSite if kind == "site" else mujoco.mj_jacBody)(m, data, jac, None, j)
                    J[b, i, :, :nq] = jac
            return
        for b, row in enumerate(flat):
            for i in range(nq):
                e = np.zeros(nq)
                e[i] = h
                J[b, :, :, i] = (at(row[:nq] + e, data) - at(row[:nq] - e, data)) / (2 * h)

    def host_jacobian(x: np.ndarray) -> np.ndarray:
        x = np.asarray(x)
        flat = x.reshape(-1, x.shape[-1]).astype(np.float64)
        J = np.zeros((flat.shape[0], k, 3, x.shape[-1]))
        with own_data() as data:
            jacobian_rows(flat, J, data)
        return J.reshape(x.shape[:-1] + (k, 3, x.shape[-1])).astype(x.dtype)

    def call(name, fn, x, shape):
        out = jax.ShapeDtypeStruct(x.shape[:-1] + shape, x.dtype)
        return host_call.call(f"{key}/{name}", fn, out, x, vmap_method="broadcast_all")

    @jax.custom_jvp
    def points(x: jax.Array) -> jax.Array:
        return call("points", host_points, x, (k, 3))

    @points.defjvp
    def _jvp(primals, tangents):
        (x,), (dx,) = primals, tangents
        J = call("jacobian", host_jacobian, x, (k, 3, x.shape[-1]))
        return points(x), jnp.einsum("...kcn,...n->...kc", J, dx)

    return points
