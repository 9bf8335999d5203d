"""What a user needs to write a task for a model: the state map and the model's limits.

``describe`` returns plain data (printed by ``python -m experiments.inspect``): nx, nu,
the label of every state coordinate [qpos, qvel, act] with joint names and quaternion
order (w, x, y, z), qpos0, actuators with ctrlrange, timestep, keyframes, sites and
bodies (names usable in ``task.goals``), and whether MJX can load the model.
"""

from __future__ import annotations

import contextlib
import io

import mujoco
import numpy as np

from mjx_surrogate.systems.system import state_labels


def _names(m: mujoco.MjModel, obj, count: int) -> list[str]:
    prefix = {mujoco.mjtObj.mjOBJ_ACTUATOR: "actuator"}.get(obj, "#")
    return [mujoco.mj_id2name(m, obj, i) or f"{prefix}{i}" for i in range(count)]


def mjx_support(m: mujoco.MjModel) -> str:
    """ "yes", or why ``mjx.put_model`` refuses the model."""
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            from mujoco import mjx

            mjx.put_model(m)
    except Exception as exc:  # MJX raises NotImplementedError / ValueError for features it lacks
        return f"no ({type(exc).__name__}: {' '.join(str(exc).split())[:200]})"
    return "yes"


def describe(m: mujoco.MjModel, check_mjx: bool = True) -> dict:
    """The model's state map, limits and named objects as plain data."""
    A = mujoco.mjtObj
    limited = m.actuator_ctrllimited.astype(bool)
    actuators = []
    for i, name in enumerate(_names(m, A.mjOBJ_ACTUATOR, m.nu)):
        lo, hi = m.actuator_ctrlrange[i] if limited[i] else (-np.inf, np.inf)
        actuators.append({"name": name, "ctrlrange": [float(lo), float(hi)], "limited": bool(limited[i])})
    keys = []
    for i, name in enumerate(_names(m, A.mjOBJ_KEY, m.nkey)):
        keys.append({"name": name, "qpos": m.key_qpos[i].tolist(), "ctrl": m.key_ctrl[i].tolist()})
    return {
        "nq": m.nq,
        "nv": m.nv,
        "na": m.na,
        "nx": m.nq + m.nv + m.na,
        "nu": m.nu,
        "state": state_labels(m),
        "qpos0": m.qpos0.tolist(),
        "timestep": float(m.opt.timestep),
        "integrator": mujoco.mjtIntegrator(m.opt.integrator).name,
        "actuators": actuators,
        "keyframes": keys,
        "sites": [n for n in _names(m, A.mjOBJ_SITE, m.nsite)],
        "bodies": [n for n in _names(m, A.mjOBJ_BODY, m.nbody)],
        "contacts_possible": bool(m.npair > 0 or (m.geom_contype.any() and m.geom_conaffinity.any())),
        "mjx": mjx_support(m) if check_mjx else "not checked",
    }


def render(info: dict) -> str:
    """``describe`` as text, one screen for a small model."""
    lines = [
        f"nx = {info['nx']} (nq {info['nq']} + nv {info['nv']} + na {info['na']}), nu = {info['nu']}, "
        f"timestep {info['timestep']:g} s ({info['integrator']})",
        "state x = [qpos, qvel, act] (quaternions as w, x, y, z):",
    ]
    lines += [f"  x[{i}] {label}" for i, label in enumerate(info["state"])]
    lines.append("qpos0: " + np.array2string(np.asarray(info["qpos0"]), precision=4, separator=", "))
    lines.append("actuators (u):")
    for i, a in enumerate(info["actuators"]):
        rng = f"ctrlrange [{a['ctrlrange'][0]:g}, {a['ctrlrange'][1]:g}]" if a["limited"] else "unlimited"
        lines.append(f"  u[{i}] {a['name']}: {rng}")
    if info["keyframes"]:
        lines.append("keyframes: " + ", ".join(k["name"] for k in info["keyframes"]))
    else:
        lines.append("keyframes: none")
    lines.append("sites: " + (", ".join(info["sites"]) or "none"))
    lines.append("bodies: " + ", ".join(info["bodies"]))
    lines.append(f"contacts possible: {info['contacts_possible']}; MJX supports it: {info['mjx']}")
    return "\n".join(lines)
