"""Tracking tasks; presets live with their systems (``mjx_surrogate.systems``).

Cost convention (one for the whole project, docs/results.md), with e(x) = x - x* or its
geodesic form (hinge angles wrapped to (-pi, pi], each quaternion block replaced by
(0, rotation vector of q*^-1 q)) or its chordal form (each hinge's error d replaced by the
chord 2 sin(d / 2), whose square is |(cos d, sin d) - (1, 0)|^2 = 2 (1 - cos d): smooth
and periodic, the angle cost of hydrax's swing-up tasks) and p_k(x) the world position of
goal point k:

    l(x, u) = 1/2 e' Q e + 1/2 (u - u_ref)' R (u - u_ref) + sum_k 1/2 w_k |p_k(x) - p_k*|^2
    l_f(x)  = 1/2 e' Q_f e + sum_k 1/2 w_f,k |p_k(x) - p_k*|^2
    J = sum_{t<T} l(x_t, u_t) + l_f(x_T)

A moving target (``motion``) puts the targets of stage t at p_k* + d_k(n + t), d the
motion's displacement after n + t control steps, n the control step of the episode at
which the horizon starts (0 offline; set by :func:`at_step` in closed loop).

A task that ends within its horizon (``end`` = E < T: an MPC plan near the end of a
finite-time task, :func:`at_step`) keeps its terminal cost at the task's end and only the
control effort after it:

    J_E = sum_{t<E} l(x_t, u_t) + l_f(x_E) + sum_{E<=t<T} 1/2 (u_t - u_ref)' R (u_t - u_ref)

Costs stay analytic (derivatives by autodiff); p_k comes from the model's kinematics,
the dynamics stay a black box.
"""

from __future__ import annotations

import dataclasses
from typing import Callable, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from mjx_surrogate import cost as cost_lib

PointsFn = Callable[[jax.Array], jax.Array]  # x [nx] -> goal point positions [k, 3]


@struct.dataclass
class Task:
    """x0, x_goal [nx]; Q, Q_f [nx, nx], or [nx] for a diagonal (held as its diagonal, so that
    a grid of many cells has no nx x nx array: :func:`quadratic`); R [nu, nu]; u_min, u_max,
    u_ref [nu] (limits may be +-inf); point goals: targets [k, 3], weights, final_weights [k]
    and ``points`` (static); ``motion`` (static, None: the targets stay): control step n (an
    int32 scalar) -> the targets' displacement [k, 3] after n steps, and ``start``: the
    control step of an episode at which the horizon starts (int32 scalar, set by
    :func:`at_step`; None: 0).
    ``hinges`` (qpos indices wrapped, or measured by their chord where ``chordal``) and
    ``quats`` (first qpos index of each quaternion) are empty for the Euclidean state
    error. ``deadline`` (static): the control step of an
    episode at which the task ends, for a receding horizon that shrinks to it (None: the
    horizon recedes); ``end``: the stage within the horizon at which it ends (an int32
    scalar, 0 .. T; None: T), set by :func:`at_step`. ``gauss_newton`` (static): point goals
    and a chordal error get Gauss-Newton's Hessian (:func:`task_cost`), else the exact one."""

    x0: jax.Array
    x_goal: jax.Array
    Q: jax.Array
    Q_f: jax.Array
    R: jax.Array
    u_min: jax.Array
    u_max: jax.Array
    u_ref: jax.Array
    targets: jax.Array
    weights: jax.Array
    final_weights: jax.Array
    T: int = struct.field(pytree_node=False)
    hinges: tuple = struct.field(pytree_node=False, default=())
    quats: tuple = struct.field(pytree_node=False, default=())
    points: PointsFn | None = struct.field(pytree_node=False, default=None)
    deadline: int | None = struct.field(pytree_node=False, default=None)
    end: jax.Array | None = None
    motion: Callable[[jax.Array], jax.Array] | None = struct.field(pytree_node=False, default=None)
    start: jax.Array | None = None
    chordal: bool = struct.field(pytree_node=False, default=False)
    gauss_newton: bool = struct.field(pytree_node=False, default=True)


def quadratic(e: jax.Array, W: jax.Array) -> jax.Array:
    """e' W e for e [n] and a weight W [n, n] or its diagonal [n]."""
    return (e * W) @ e if W.ndim == 1 else e @ W @ e


def weight_matrix(W) -> np.ndarray | jax.Array:
    """A weight [n, n] or its diagonal [n] as the matrix [n, n] (for small systems only)."""
    return jnp.diag(W) if jnp.ndim(W) == 1 else W


def weight_diagonal(W) -> np.ndarray:
    """The diagonal [n] of a weight [n, n] or [n] (host-side, NumPy)."""
    W = np.asarray(W)
    return W if W.ndim == 1 else np.diagonal(W)


def half_ranges(u_min: np.ndarray, u_max: np.ndarray) -> np.ndarray:
    """[nu] half of each control's range, 1 where a control is unlimited: the scale of a
    control in the default weights, start noise and sampling spreads."""
    lo, hi = np.asarray(u_min, float), np.asarray(u_max, float)
    return np.where(np.isfinite(hi - lo), 0.5 * (hi - lo), 1.0)


def at_step(task: Task, n: jax.Array) -> Task:
    """The horizon-T task as planned at control step n of an episode: with a ``deadline``
    D it ends at stage clip(D - n, 0, T) (the horizon shrinks to the task's end; past it
    only the control effort counts, module docstring); moving targets start n steps on;
    otherwise it is ``task``."""
    if task.motion is not None:
        task = task.replace(start=jnp.asarray(n, jnp.int32))
    if task.deadline is None:
        return task
    return task.replace(end=jnp.clip(task.deadline - n, 0, task.T).astype(jnp.int32))


def quat_error(q: jax.Array, g: jax.Array) -> jax.Array:
    """Rotation vector [3] of g^-1 q for unit quaternions q, g [4] (w, x, y, z), the short
    way round; smooth at zero."""
    q = q / jnp.linalg.norm(q)
    w = g[0] * q[0] + g[1:] @ q[1:]
    v = g[0] * q[1:] - q[0] * g[1:] - jnp.cross(g[1:], q[1:])
    sign = jnp.where(w < 0, -1.0, 1.0)
    w, v = sign * w, sign * v
    n2 = v @ v
    small = n2 < 1e-12
    n = jnp.sqrt(jnp.where(small, 1.0, n2))
    return jnp.where(small, 2.0 / w, 2.0 * jnp.arctan2(n, w) / n) * v


def state_error(task: Task, x: jax.Array) -> jax.Array:
    """e(x) [nx]: x - x_goal, hinge angles wrapped (or their chords), quaternion blocks as
    (0, rotvec)."""
    e = x - task.x_goal
    if task.hinges and task.chordal:
        chord = np.isin(np.arange(x.shape[-1]), task.hinges)
        e = jnp.where(chord, 2.0 * jnp.sin(e / 2.0), e)
    elif task.hinges:  # a constant mask, not a gather and a scatter: a smaller program
        wrap = np.isin(np.arange(x.shape[-1]), task.hinges)
        e = jnp.where(wrap, jnp.mod(e + jnp.pi, 2 * jnp.pi) - jnp.pi, e)
    if task.quats:
        q = [x[a : a + 4] for a in task.quats]
        g = [task.x_goal[a : a + 4] for a in task.quats]
        # several blocks: one vmapped error, so that the program does not grow with their
        # number; one block: the plain call (vmapped, its derivatives round differently)
        rot = [quat_error(q[0], g[0])] if len(q) == 1 else jax.vmap(quat_error)(jnp.stack(q), jnp.stack(g))
        for a, r in zip(task.quats, rot):
            e = e.at[a].set(0.0).at[a + 1 : a + 4].set(r)
    return e


def targets_at(task: Task, t) -> jax.Array:
    """The point goals' targets [k, 3] at stage t of the horizon (module docstring)."""
    if task.motion is None:
        return task.targets
    n = t if task.start is None else task.start + t
    return task.targets + task.motion(jnp.asarray(n, jnp.int32)).astype(task.targets.dtype)


def _point_terms(task: Task, x: jax.Array, weights: jax.Array, t) -> jax.Array:
    if task.points is None:
        return jnp.zeros((), x.dtype)
    d = task.points(x) - targets_at(task, t)
    return 0.5 * jnp.sum(weights * jnp.sum(d**2, axis=-1))


def point_distances(task: Task, X: jax.Array) -> jax.Array:
    """[N+1]: the goal points' mean distance (m) from their targets at each state of X
    [N+1, nx] of an episode (moving targets where they are at that step); needs points."""
    n = jnp.arange(X.shape[0], dtype=jnp.int32)
    d = jax.vmap(lambda x, t: task.points(x) - targets_at(task, t))(X, n)
    return jnp.mean(jnp.linalg.norm(d, axis=-1), axis=-1)


def running_cost(task: Task, x: jax.Array, u: jax.Array, t=0) -> jax.Array:
    """l(x, u) for x [nx], u [nu] at stage t (module docstring)."""
    e, du = state_error(task, x), u - task.u_ref
    return 0.5 * quadratic(e, task.Q) + 0.5 * du @ task.R @ du + _point_terms(task, x, task.weights, t)


def terminal_cost(task: Task, x: jax.Array, t=None) -> jax.Array:
    """l_f(x) for x [nx], the targets' of stage t (None: T)."""
    e, t = state_error(task, x), task.T if t is None else t
    return 0.5 * quadratic(e, task.Q_f) + _point_terms(task, x, task.final_weights, t)


def has_terminal(task: Task) -> bool:
    """Whether the task has a terminal term (Q_f or a final point weight); needs concrete arrays."""
    return bool(np.any(np.asarray(task.Q_f))) or bool(np.any(np.asarray(task.final_weights)))


def goal_cost(task: Task, x: jax.Array, terminal: bool | None = None, t=None) -> jax.Array:
    """The task's own measure of distance to the goal: l_f(x), or, for a task with no
    terminal term, the state part of l(x, u_ref); moving targets at stage t (None: T).
    ``terminal``: :func:`has_terminal`, given when the task's arrays are traced."""
    t = task.T if t is None else t
    if terminal if terminal is not None else has_terminal(task):
        return terminal_cost(task, x, t)
    e = state_error(task, x)
    return 0.5 * quadratic(e, task.Q) + _point_terms(task, x, task.weights, t)


def effort_cost(task: Task, u: jax.Array) -> jax.Array:
    """1/2 (u - u_ref)' R (u - u_ref) for u [nu]."""
    du = u - task.u_ref
    return 0.5 * du @ task.R @ du


def stage_cost(task: Task, x: jax.Array, u: jax.Array, t: jax.Array) -> jax.Array:
    """The cost of stage t of a task that ends at stage ``task.end`` (module docstring):
    l(x, u) before the end, l_f(x) and the effort at it, the effort alone after it."""
    end = task.T if task.end is None else task.end
    before, at_end = t < end, t == end
    # the state weights of the stage: Q before the end, Q_f at it (one error, one points call)
    Q, Q_f = task.Q, task.Q_f
    if Q.ndim != Q_f.ndim:  # one a diagonal, the other a matrix
        Q, Q_f = weight_matrix(Q), weight_matrix(Q_f)
    Q = jnp.where(before, Q, 0.0) + jnp.where(at_end, Q_f, 0.0)
    w = jnp.where(before, task.weights, 0.0) + jnp.where(at_end, task.final_weights, 0.0)
    e = state_error(task, x)
    return 0.5 * quadratic(e, Q) + _point_terms(task, x, w, t) + effort_cost(task, u)


def final_cost(task: Task, x: jax.Array) -> jax.Array:
    """The cost of the horizon's last state x [nx]: l_f(x), or 0 if the task ended before it."""
    if task.end is None:
        return terminal_cost(task, x)
    return jnp.where(task.end == task.T, terminal_cost(task, x), 0.0)


def task_cost(task: Task) -> cost_lib.Cost:
    """The task's cost as the solver's :class:`~mjx_surrogate.cost.Cost` (timed where the
    task ends within its horizon); with point goals, their Hessian is Gauss-Newton's
    (:func:`point_goal_derivatives`), and so is a chordal state error's
    (:func:`chordal_derivatives`), unless ``task.gauss_newton`` is off (then every term is
    differentiated exactly)."""
    derivatives = None  # autodiff of every term
    if task.gauss_newton and task.chordal and task.hinges:
        derivatives = lambda X, U: chordal_derivatives(task, X, U)  # noqa: E731
    elif task.gauss_newton and task.points is not None:
        derivatives = lambda X, U: point_goal_derivatives(task, X, U)  # noqa: E731
    if task.end is not None or task.motion is not None:
        return cost_lib.Cost(
            lambda x, u, t: stage_cost(task, x, u, t), lambda x: final_cost(task, x), derivatives, True
        )
    return cost_lib.Cost(lambda x, u: running_cost(task, x, u), lambda x: terminal_cost(task, x), derivatives)


def point_goal_derivatives(task: Task, X: jax.Array, U: jax.Array):
    """Cost derivatives (the shapes of ``riccati.cost_derivatives``) with the point terms
    1/2 w |p(x) - target|^2 taken to Gauss-Newton's order: gradient J'W r, Hessian J'W J
    with J = dp/dx [k, 3, nx] (one ``jacfwd`` of the kinematics). The exact Hessian adds
    sum_k w_k r_k . d2p_k/dx2, which vanishes at the target, and needs second derivatives
    of the MJX kinematics, whose compile is long (docs/performance.md). The rest of the cost
    is differentiated exactly."""
    plain = dataclasses.replace(task, points=None)
    plain_cost = task_cost(plain)

    def gn(x, weights, t):
        r = task.points(x) - targets_at(task, t)  # [k, 3]
        J = jax.jacfwd(task.points)(x)  # [k, 3, nx]
        g = jnp.einsum("k,kc,kcn->n", weights, r, J)
        H = jnp.einsum("k,kcm,kcn->mn", weights, J, J)
        return g, H

    running = cost_lib.hessian_and_gradient(plain_cost.running, (0, 1))
    ((lxx, _), (lux, luu)), (lx, lu) = jax.vmap(running)(*cost_lib.stage_inputs(plain_cost, X, U))
    Vxx, Vx = cost_lib.hessian_and_gradient(plain_cost.terminal)(X[-1])
    stages = jnp.arange(U.shape[0], dtype=jnp.int32)
    if task.end is None:
        g, H = jax.vmap(lambda x, t: gn(x, task.weights, t))(X[:-1], stages)
        gT, HT = gn(X[-1], task.final_weights, task.T)
    else:  # the points' weights of each stage: running before the end, final at it
        t = stages[:, None]
        w = jnp.where(t < task.end, task.weights, 0.0) + jnp.where(t == task.end, task.final_weights, 0.0)
        g, H = jax.vmap(gn)(X[:-1], w, stages)
        gT, HT = gn(X[-1], jnp.where(task.end == task.T, task.final_weights, 0.0), task.T)
    return lx + g, lu, lxx + H, luu, lux, Vx + gT, Vxx + HT


def chordal_derivatives(task: Task, X: jax.Array, U: jax.Array):
    """Cost derivatives with the state term 1/2 e' Q e of a chordal state error taken to
    Gauss-Newton's order, as MuJoCo MPC treats its residuals: gradient J'Q e, Hessian J'Q J
    with J = de/dx (diagonal: cos(d / 2) at each hinge, 1 elsewhere). The exact Hessian of a
    hinge's 2 (1 - cos d) is Q cos d, negative below the horizontal (a swing-up's start), where
    a Newton step climbs; J'Q J stays positive semi-definite. The effort and any point goals
    as :func:`task_cost` without the state term."""
    rest = task_cost(dataclasses.replace(task, chordal=False, hinges=(), Q=0 * task.Q, Q_f=0 * task.Q_f))
    if rest.derivatives is not None:  # point goals
        lx, lu, lxx, luu, lux, Vx, Vxx = rest.derivatives(X, U)
    else:
        running = cost_lib.hessian_and_gradient(rest.running, (0, 1))
        ((lxx, _), (lux, luu)), (lx, lu) = jax.vmap(running)(*cost_lib.stage_inputs(rest, X, U))
        Vxx, Vx = cost_lib.hessian_and_gradient(rest.terminal)(X[-1])
    chord = np.isin(np.arange(X.shape[-1]), task.hinges)
    e = jax.vmap(lambda x: state_error(task, x))(X)  # [T+1, nx]
    J = jnp.where(chord, jnp.cos((X - task.x_goal) / 2.0), 1.0)  # de/dx, diagonal
    T = U.shape[0]
    Q, Q_f = weight_matrix(task.Q), weight_matrix(task.Q_f)
    if task.end is None:
        Qs, QT = jnp.broadcast_to(Q, (T,) + Q.shape), Q_f
    else:
        t = jnp.arange(T)[:, None, None]
        Qs = jnp.where(t < task.end, Q, 0.0) + jnp.where(t == task.end, Q_f, 0.0)
        QT = jnp.where(task.end == task.T, Q_f, 0.0)
    Je, JT = J[:-1], J[-1]
    gx = jnp.einsum("ti,tij,tj->ti", Je, Qs, e[:-1])
    Hx = Je[:, :, None] * Qs * Je[:, None, :]
    return lx + gx, lu, lxx + Hx, luu, lux, Vx + JT * (QT @ e[-1]), Vxx + JT[:, None] * QT * JT[None, :]


def trajectory_cost(task: Task, X: jax.Array, U: jax.Array) -> jax.Array:
    """J of X [N+1, nx], U [N, nu] (+inf if X is not finite or blew up); batch with vmap.
    Moving targets end at stage N (an episode's length, whatever the task's T)."""
    if task.motion is not None and task.end is None and U.shape[0] != task.T:
        task = task.replace(T=U.shape[0])
    return cost_lib.trajectory_cost(task_cost(task), X, U)


class TaskPreset(NamedTuple):
    """A preset: the system it belongs to and a builder (nq, nv, nu) -> dict of numpy fields."""

    system: str
    build: Callable[[int, int, int], dict]
    doc: str


def state(nq: int, nv: int, **qpos: float) -> np.ndarray:
    """A state [nq + nv] of zeros with the named qpos entries set: ``state(2, 2, q0=pi)``."""
    x = np.zeros(nq + nv)
    for idx, v in qpos.items():
        x[int(idx[1:])] = v
    return x


def make_task(
    x0,
    x_goal,
    Q,
    Q_f,
    R,
    T: int,
    u_min=None,
    u_max=None,
    dtype=None,
    *,
    u_ref=None,
    targets=None,
    weights=None,
    final_weights=None,
    points: PointsFn | None = None,
    motion: Callable[[jax.Array], jax.Array] | None = None,
    hinges: tuple = (),
    quats: tuple = (),
    chordal: bool = False,
    gauss_newton: bool = True,
) -> Task:
    """Assemble a :class:`Task` from array-likes (shapes checked by ``resolution.resolve``);
    Q, Q_f [nx, nx] or their diagonals [nx]; ``motion``: the targets' displacement
    after n control steps (:class:`Task`), for moving targets."""
    dtype = dtype or jnp.result_type(float)
    nu = np.shape(R)[0]
    lo = np.full(nu, -np.inf) if u_min is None else np.asarray(u_min, float)
    hi = np.full(nu, np.inf) if u_max is None else np.asarray(u_max, float)
    # converted by NumPy, then placed: no XLA program runs before the task is checked
    arr = lambda a: jax.device_put(np.asarray(a, float).astype(np.dtype(dtype)))  # noqa: E731
    k = 0 if targets is None else len(targets)
    return Task(
        x0=arr(x0),
        x_goal=arr(x_goal),
        Q=arr(Q),
        Q_f=arr(Q_f),
        R=arr(R),
        u_min=arr(lo),
        u_max=arr(hi),
        u_ref=arr(np.zeros(nu) if u_ref is None else u_ref),
        targets=arr(np.zeros((0, 3)) if targets is None else np.reshape(targets, (k, 3))),
        weights=arr(np.zeros(k) if weights is None else weights),
        final_weights=arr(np.zeros(k) if final_weights is None else final_weights),
        T=int(T),
        hinges=tuple(int(i) for i in hinges),
        quats=tuple(int(i) for i in quats),
        points=points if k else None,
        motion=motion if k else None,
        chordal=bool(chordal),
        gauss_newton=bool(gauss_newton),
    )
