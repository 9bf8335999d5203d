"""Positions of named sites and bodies as a differentiable function of the state.

Task costs on points (a fingertip at a target, a nose, an end effector) need p(x); it
comes from MJX forward kinematics on the same model, so the cost stays analytic and
autodiff gives its derivatives. The dynamics are never differentiated here.
"""

from __future__ import annotations

import contextlib
import io

import jax
import jax.numpy as jnp
import mujoco

from mjx_surrogate.errors import ConfigError

with contextlib.redirect_stdout(io.StringIO()):  # silence "Failed to import warp"
    from mujoco import mjx

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
