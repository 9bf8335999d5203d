"""What a user needs to write a task for a model: the state map and the model's limits.

``describe`` returns plain data (printed by ``python -m experiments.inspect``): nx, nu,
the label of every state coordinate [qpos, qvel, act] with joint names and quaternion
order (w, x, y, z), qpos0, actuators (kind, what they drive, gear, control and force
limits), sensors, mocap bodies (moved by the simulation's user, not by controls),
timestep, keyframes, sites and bodies (names usable in ``task.goals``), and whether MJX
can load the model.
"""

from __future__ import annotations

import mujoco
import numpy as np

from mjx_surrogate.systems.backend_mjx import MjxUnsupported, put_model
from mjx_surrogate.systems.system import state_labels


def _names(m: mujoco.MjModel, obj, count: int) -> list[str]:
    prefix = {mujoco.mjtObj.mjOBJ_ACTUATOR: "actuator"}.get(obj, "#")
    return [mujoco.mj_id2name(m, obj, i) or f"{prefix}{i}" for i in range(count)]


def mjx_support(m: mujoco.MjModel) -> str:
    """ "yes", or why the MJX backend cannot simulate the model
    (:func:`~mjx_surrogate.systems.backend_mjx.put_model`)."""
    try:
        put_model(m)
    except MjxUnsupported as exc:
        return f"no ({exc.reason})"
    return "yes"


def actuator_kind(m: mujoco.MjModel, i: int) -> str:
    """ "motor", "position servo", "velocity servo", "muscle", or the gain/bias types."""
    gain, bias = int(m.actuator_gaintype[i]), int(m.actuator_biastype[i])
    if m.actuator_dyntype[i] == mujoco.mjtDyn.mjDYN_MUSCLE:
        return "muscle"
    if gain == mujoco.mjtGain.mjGAIN_FIXED and bias == mujoco.mjtBias.mjBIAS_NONE:
        return "motor"
    if gain == mujoco.mjtGain.mjGAIN_FIXED and bias == mujoco.mjtBias.mjBIAS_AFFINE:
        kp, kv = m.actuator_biasprm[i, 1], m.actuator_biasprm[i, 2]
        return "position servo" if kp != 0 else ("velocity servo" if kv != 0 else "motor")
    return f"gain {_enum(mujoco.mjtGain(gain))}, bias {_enum(mujoco.mjtBias(bias))}"


def _enum(value) -> str:
    """mjTRN_JOINT -> joint."""
    return value.name.split("_", 1)[1].lower()


def _target(m: mujoco.MjModel, i: int) -> str:
    trn = mujoco.mjtTrn(int(m.actuator_trntype[i]))
    obj = {
        mujoco.mjtTrn.mjTRN_JOINT: mujoco.mjtObj.mjOBJ_JOINT,
        mujoco.mjtTrn.mjTRN_JOINTINPARENT: mujoco.mjtObj.mjOBJ_JOINT,
        mujoco.mjtTrn.mjTRN_TENDON: mujoco.mjtObj.mjOBJ_TENDON,
        mujoco.mjtTrn.mjTRN_SITE: mujoco.mjtObj.mjOBJ_SITE,
        mujoco.mjtTrn.mjTRN_BODY: mujoco.mjtObj.mjOBJ_BODY,
        mujoco.mjtTrn.mjTRN_SLIDERCRANK: mujoco.mjtObj.mjOBJ_SITE,
    }.get(trn)
    tid = int(m.actuator_trnid[i, 0])
    name = (mujoco.mj_id2name(m, obj, tid) if obj is not None else None) or f"#{tid}"
    return f"{_enum(trn)} {name}"


def _range(limited: bool, r) -> list[float]:
    return [float(r[0]), float(r[1])] if limited else [-np.inf, np.inf]


def describe(m: mujoco.MjModel, check_mjx: bool = True) -> dict:
    """The model's state map, limits and named objects as plain data."""
    A = mujoco.mjtObj
    limited = m.actuator_ctrllimited.astype(bool)
    actuators = []
    for i, name in enumerate(_names(m, A.mjOBJ_ACTUATOR, m.nu)):
        lo, hi = m.actuator_ctrlrange[i] if limited[i] else (-np.inf, np.inf)
        actuators.append(
            {
                "name": name,
                "ctrlrange": [float(lo), float(hi)],
                "limited": bool(limited[i]),
                "kind": actuator_kind(m, i),
                "drives": _target(m, i),
                "gear": float(m.actuator_gear[i, 0]),
                "forcerange": _range(bool(m.actuator_forcelimited[i]), m.actuator_forcerange[i]),
                "activation": m.actuator_dyntype[i] != mujoco.mjtDyn.mjDYN_NONE,
            }
        )
    sensors = [
        {
            "name": n,
            "type": _enum(mujoco.mjtSensor(int(m.sensor_type[i]))),
            "dim": int(m.sensor_dim[i]),
        }
        for i, n in enumerate(_names(m, A.mjOBJ_SENSOR, m.nsensor))
    ]
    mocap = [n for b, n in enumerate(_names(m, A.mjOBJ_BODY, m.nbody)) if m.body_mocapid[b] >= 0]
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
        "sensors": sensors,
        "mocap_bodies": mocap,
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
    lines.append(
        "actuators (u):" if info["actuators"] else "actuators: none (nothing for a controller to drive)"
    )
    for i, a in enumerate(info["actuators"]):
        rng = f"ctrlrange [{a['ctrlrange'][0]:g}, {a['ctrlrange'][1]:g}]" if a["limited"] else "unlimited"
        force = a["forcerange"]
        extra = f", force within [{force[0]:g}, {force[1]:g}]" if np.isfinite(force).all() else ""
        extra += ", with activation dynamics" if a["activation"] else ""
        lines.append(f"  u[{i}] {a['name']}: {a['kind']} on {a['drives']}, gear {a['gear']:g}, {rng}{extra}")
    if info["mocap_bodies"]:
        lines.append(
            "mocap bodies (positioned by the user, not part of the state or the controls): "
            + ", ".join(info["mocap_bodies"])
        )
    sensors = info["sensors"]
    if sensors:
        shown = ", ".join(f"{s['name']} ({s['type']}, {s['dim']})" for s in sensors[:12])
        more = f" and {len(sensors) - 12} more" if len(sensors) > 12 else ""
        lines.append(f"sensors (not used by the solver, which sees the state): {shown}{more}")
    else:
        lines.append("sensors: none")
    if info["keyframes"]:
        lines.append("keyframes: " + ", ".join(k["name"] for k in info["keyframes"]))
    else:
        lines.append("keyframes: none")
    lines.append("sites: " + (", ".join(info["sites"]) or "none"))
    lines.append("bodies: " + ", ".join(info["bodies"]))
    lines.append(f"contacts possible: {info['contacts_possible']}; MJX supports it: {info['mjx']}")
    return "\n".join(lines)
