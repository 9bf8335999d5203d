"""Defaults derived from the model: what a field left unset means, in one place.

Registered systems (pendulum, cartpole, fish, swimmer) keep the paper's settings. A user's
MJCF model (``system.name = "mjcf"``) gets settings that hold on robots as downloaded
(contacts, servos, free joints), each documented in docs/configs.md:

* precision: float64 (float32 round-off swamps the small perturbations that contacts need;
  the dm_control humanoid made no progress in float32);
* identification: n_samples = max(20, 2 (nx + nu)), sigma = 1e-6 in float64 (up to 2e-5
  where actuated joints have dry friction: :func:`friction_sigma`), the noise floor
  (entries below the difference quotients' resolution are zero), and the given start x_0
  not perturbed (t = 0 identifies B_0 alone), and on a model with loose objects (trees no
  actuator moves) the t-test at 3 standard errors (:func:`default_significance`);
* start: the controls that hold x0 still (:func:`hold_controls`);
* task preset ``hold``: keep x0 (the model's qpos0 or ``task.x0_keyframe``) for 50 control
  steps, weights scaled to the actuators' ranges (:func:`hold_task`).
"""

from __future__ import annotations

import copy

import jax.numpy as jnp
import mujoco
import numpy as np

from mjx_surrogate.identification.sysid import SysIdParams
from mjx_surrogate.tasks import half_ranges

HOLD_T = 50  # control steps of the hold task
FRICTION_SIGMA_MAX = 2e-5  # the largest default perturbation on a model with dry friction
USER_SYSTEMS = ("mjcf", "python")  # a user's MJCF model, a user's function black box
FUNCTION_SYSTEMS = ("lorenz", "f8", "python")  # black boxes given as functions


def default_n_samples(nx: int, nu: int, reduced: bool = False) -> int:
    """Identification samples per time step when sysid.n_samples is unset; for a reduced
    scheme the snapshot rollouts (the basis's largest rank), min(nx, max(16, 4 nu))."""
    if reduced:
        return min(nx, max(16, 4 * nu))
    return max(20, 2 * (nx + nu))


def default_sigma(registered: bool) -> float:
    """Identification perturbation std when the config leaves it unset.

    Registered systems keep D2C 2.0's 1e-3 (the paper's setting). A user's model gets 1e-6
    in float64 (D2C 2.0 later used 1e-7) and 1e-3 in float32: perturbations of 1e-3
    straddle contact events, and the LTV fitted across them is a smoothed model that
    stalls iLQR far from the optimum (half-cheetah: 140x the oracle's cost at 1e-3, 3 %
    below it at 1e-6; docs/performance.md). 1e-6 is far above float64 round-off (relative
    error eps / sigma = 2e-10) but not in float32 (0.1).
    """
    if registered or np.finfo(jnp.result_type(float)).eps > 1e-10:
        return SysIdParams().sigma_x
    return 1e-6


def default_noise_floor(system_name: str) -> float:
    """sysid.noise_floor when unset: 10 for a user's model (identified entries below
    10 eps |x| / sigma are zero: ``sysid.below_resolution``), 0 (off) for registered ones,
    whose paper settings stay as published."""
    return 10.0 if system_name in USER_SYSTEMS else 0.0


LOOSE_OBJECT_SIGNIFICANCE = 3.0  # the t-test's threshold on a user's model with loose objects


def loose_bodies(m: mujoco.MjModel) -> list[str]:
    """Names of the kinematic trees (bodies whose parent is the world) that have degrees
    of freedom on which no actuator acts, judged by the actuator moments at qpos0: loose
    objects such as a ball, a door on its hinge or a target marker."""
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    moment = np.zeros((m.nu, m.nv))
    if m.nu:
        mujoco.mju_sparse2dense(moment, d.actuator_moment, d.moment_rownnz, d.moment_rowadr, d.moment_colind)
    actuated = np.any(moment != 0.0, axis=0)  # [nv]
    trees: dict[int, bool] = {}
    for v in range(m.nv):
        root = int(m.body_rootid[m.dof_bodyid[v]])
        trees[root] = trees.get(root, False) or bool(actuated[v])
    body = mujoco.mjtObj.mjOBJ_BODY
    return [mujoco.mj_id2name(m, body, r) or f"body {r}" for r, acted_on in trees.items() if not acted_on]


def default_significance(system_name: str, m: mujoco.MjModel | None) -> float:
    """sysid.significance when unset: LOOSE_OBJECT_SIGNIFICANCE (3) for a user's
    MuJoCo model with loose objects (:func:`loose_bodies`), else 0 (off).

    A loose object that bounces during a step leaves a large residual in its rows, which
    least squares spreads over every regressor (the dm_control manipulator's ball and peg
    came out with control coefficients up to 3e4); the t-test zeroes what the data cannot
    tell from zero (``sysid.significance``). A model without loose objects keeps it off:
    on locomotion the rows fitted across contact events carry the averaged slope the solve
    needs (docs/method.md)."""
    if system_name not in USER_SYSTEMS or m is None or not loose_bodies(m):
        return 0.0
    return LOOSE_OBJECT_SIGNIFICANCE


def default_perturb_x0(system_name: str) -> bool:
    """sysid.perturb_x0 when unset: False for a user's model (x_0 is given, so the
    one-step schemes identify B_0 alone: ``sysid._one_step_perturbations``), True for
    registered ones (D2C 2.0's design, as published)."""
    return system_name not in USER_SYSTEMS


def default_hold_limits(system_name: str) -> bool:
    """sysid.hold_limits when unset: True for a user's model (the one-step schemes
    leave a joint that rests on its limit unperturbed: ``sysid.hold_at_limits``), False for
    registered ones (D2C 2.0's design, as published)."""
    return system_name in USER_SYSTEMS


def default_x64(system_name: str) -> bool:
    """experiment.x64 when unset: float64 for a user's model and every function black box
    (lorenz, f8, the PDEs), float32 for the registered MuJoCo systems."""
    from mjx_surrogate.systems.registry import is_function_system

    return system_name in USER_SYSTEMS + FUNCTION_SYSTEMS or is_function_system(system_name)


def default_init(system_name: str) -> str:
    """solver.init when unset: "hold" for a user's MJCF model (zero controls send position
    servos to joint angle 0), "u_ref" for a user's function (the task's control
    reference, zeros unless given), "zeros" for registered ones (the paper's start)."""
    return {"mjcf": "hold", "python": "u_ref"}.get(system_name, "zeros")


USER_STALL_RESTARTS = 4  # spread restarts after a stalled solve on a user's black box


def default_stall_restarts(system_name: str) -> int:
    """solver.stall_restarts when unset: 4 for a user's model or function (a stalled solve
    on a contact model is often a poorer local minimum than a nearby start reaches:
    :func:`mjx_surrogate.runs.restart.restart_stalled`), 0 for registered ones (the paper's
    single start)."""
    return USER_STALL_RESTARTS if system_name in USER_SYSTEMS else 0


def _data_at(m: mujoco.MjModel, x: np.ndarray) -> mujoco.MjData:
    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:] = x[: m.nq], x[m.nq : m.nq + m.nv]
    if m.na:
        d.act[:] = x[m.nq + m.nv :]
    mujoco.mj_forward(m, d)
    return d


def control_slopes(m: mujoco.MjModel, x: np.ndarray, u_min: np.ndarray, u_max: np.ndarray):
    """(G [nv, nu], centre [nu], f0 [nv], direct [nu]): the generalized actuator force's slope
    in each control at state ``x`` [nx], taken by a difference from the centre of the control
    ranges with the force limits off (a limit clips the force the controls ask for, it does
    not change which controls those are), the force f0 at the centre, and which actuators
    act without activation dynamics (the others' columns are 0: their force follows the
    activation in the state, not the control)."""
    lo, hi = np.asarray(u_min, float), np.asarray(u_max, float)
    free = copy.copy(m)  # force limits off: the force is then exactly affine in the control
    free.actuator_forcelimited[:] = 0
    d = _data_at(free, x)
    bounded = np.isfinite(lo) & np.isfinite(hi)
    centre = np.clip(
        np.where(bounded, 0.5 * (np.where(bounded, lo, 0.0) + np.where(bounded, hi, 0.0)), 0.0), lo, hi
    )
    step = 1e-4 * np.maximum(half_ranges(lo, hi), 1e-12)

    def forces(u: np.ndarray) -> np.ndarray:
        d.ctrl[:] = u
        mujoco.mj_fwdActuation(free, d)
        return d.qfrc_actuator.copy()

    f0 = forces(centre)
    G = np.zeros((m.nv, m.nu))
    direct = m.actuator_dyntype == mujoco.mjtDyn.mjDYN_NONE
    for j in np.flatnonzero(direct):
        u = centre.copy()
        u[j] += step[j] if centre[j] + step[j] <= hi[j] else -step[j]
        G[:, j] = (forces(u) - f0) / (u[j] - centre[j])
    return G, centre, f0, direct


def hold_controls(m: mujoco.MjModel, x: np.ndarray, u_min: np.ndarray, u_max: np.ndarray) -> np.ndarray:
    """Controls [nu] inside [u_min, u_max] whose actuator forces come closest (least squares
    in generalized forces) to what holds state ``x`` [nx] with zero acceleration: gravity,
    Coriolis, springs and contact forces by inverse dynamics (``mj_inverse``).

    Actuator force is affine in the control for actuators without activation dynamics
    (motors, position and velocity servos): :func:`control_slopes`. Actuators with
    activation dynamics and controls that move no joint get the in-range control nearest
    0. Exact where the actuators span the needed forces within their limits (a
    gravity-compensated arm); the least-squares compromise otherwise.
    """
    x = np.asarray(x, float)
    lo, hi = np.asarray(u_min, float), np.asarray(u_max, float)
    if m.nu == 0:
        return np.zeros(0)
    d = _data_at(m, x)
    d.qacc[:] = 0.0
    mujoco.mj_inverse(m, d)
    tau = d.qfrc_inverse.copy()
    G, centre, f0, direct = control_slopes(m, x, lo, hi)
    bounded = np.isfinite(lo) & np.isfinite(hi)
    nearest0 = np.clip(0.0, lo, hi)
    scale = max(float(np.abs(G).max(initial=0.0)), 1e-12)
    ridge = 1e-6 * scale  # picks the control nearest 0 along directions that move nothing
    A = np.vstack([G, ridge * np.eye(m.nu)])
    b = np.concatenate([tau - f0 + G @ centre, ridge * nearest0])
    from scipy.optimize import lsq_linear  # imported here: scipy.optimize takes 0.4 s to import

    u = lsq_linear(A, b, bounds=(lo, hi), method="bvls" if np.all(bounded) else "trf").x
    return np.clip(np.where(direct, u, nearest0), lo, hi)


def breakaway_controls(m: mujoco.MjModel, x: np.ndarray, u_min: np.ndarray, u_max: np.ndarray) -> np.ndarray:
    """[nu]: per actuator, the smallest control change that moves the actuator's force on
    a joint with dry friction (``dof_frictionloss`` f_j) by f_j, min over such joints of
    f_j / |G_ja| (:func:`control_slopes`); inf where the actuator drives no such joint.
    A smaller change leaves a joint at rest held."""
    f = np.asarray(m.dof_frictionloss, float)
    if m.nu == 0 or not np.any(f > 0):
        return np.full(m.nu, np.inf)
    G = np.abs(control_slopes(m, np.asarray(x, float), u_min, u_max)[0])  # [nv, nu]
    drives = (f[:, None] > 0) & (G > 1e-9 * max(float(G.max()), 1e-300))
    return np.min(np.where(drives, f[:, None] / np.where(drives, G, 1.0), np.inf), axis=0)


def friction_sigma(
    sigma: float, m: mujoco.MjModel, x: np.ndarray, u_min: np.ndarray, u_max: np.ndarray
) -> float:
    """The identification's default perturbation on a model whose actuated joints have dry
    friction: 10x the smallest :func:`breakaway_controls`, between the default ``sigma``
    and FRICTION_SIGMA_MAX.

    Below its break-away a joint at rest is held (MuJoCo's soft friction passes only a
    fraction of the free response), so the identified B is too small to plan with. The cap
    keeps perturbations small against contact events (:func:`default_sigma`). The rule's
    measurements on gymnasium-robotics' hands: docs/performance.md and docs/your_model.md."""
    smallest = float(np.min(breakaway_controls(m, x, u_min, u_max), initial=np.inf))
    if not np.isfinite(smallest) or sigma >= FRICTION_SIGMA_MAX:
        return sigma
    return float(min(max(sigma, float(f"{10.0 * smallest:.2g}")), FRICTION_SIGMA_MAX))


def control_weights(u_min: np.ndarray, u_max: np.ndarray) -> np.ndarray:
    """R [nu, nu] when a task gives none: 0.01 per squared half control range (0.01 where a
    control is unlimited), so that every actuator's full range costs alike."""
    return np.diag(0.01 / np.maximum(half_ranges(u_min, u_max), 1e-6) ** 2)


def hold_task(m: mujoco.MjModel, x0: np.ndarray, u_min: np.ndarray, u_max: np.ndarray) -> dict:
    """Task fields of the ``hold`` preset: stay at x0 for HOLD_T control steps.

    Q weighs positions 1 and velocities 0.01 (per coordinate of the state error), Q_f ten
    times Q, R 0.01 per squared half control range (0.01 for an unlimited control), and the
    R term pulls towards the hold controls (:func:`hold_controls`), not towards zero."""
    q = np.concatenate([np.ones(m.nq), 0.01 * np.ones(m.nv), np.zeros(m.na)])
    return {
        "T": HOLD_T,
        "x_goal": np.asarray(x0, float),
        "Q": np.diag(q),
        "Q_f": 10.0 * np.diag(q),
        "R": control_weights(u_min, u_max),
        "u_ref": hold_controls(m, x0, u_min, u_max),
    }
