"""The loop users run in real time: the plant steps on the wall clock at its own period
while the planner replans in a thread of its own from the latest measured state, and the
plant applies the newest plan by its time stamp (MuJoCo MPC's agent; hydrax's simulation
loop).

Notation: control period dt; the plant's tick k is due at wall time t_0 + k dt / speed
(``speed`` 1: real time). A plan made from the state measured at tick n carries the stamp
n; at tick k >= n the plant applies its row j = k - n (its last row past its end):

    u_k = clip(U[j] + K[j] (x_k - X[j])),    x_{k+1} = f_plant(x_k, u_k) + w_k

for a :class:`~mjx_surrogate.control.episode.Plan` (its gains K), u_k = clip(U[j]) for any
other plan with controls ``U`` (a sampling planner's spline plan).

The planner starts each replan from the newest measurement, warm-started from its newest
plan moved on to that tick (the planner's ``shift``; :func:`moved_on` for a Plan), and waits for a
new measurement when it is done before the next tick. A plan's latency, the ticks between
its stamp and its first use, is what the synchronous episode
(:func:`mjx_surrogate.control.episode.episode`, every replan done before the plant moves)
leaves out. The first plan is made from x_0 before the clock starts.
"""

from __future__ import annotations

import threading
import time
from typing import Any, Callable, NamedTuple

import jax
import mujoco
import numpy as np

from mjx_surrogate.control.episode import Plan

# replan(x [nx], plan, key, n) -> (plan, info): a planner's replan (jitted), as the
# synchronous episode calls it
Replan = Callable[..., tuple]


class RealTimePlanner(NamedTuple):
    """A planner as the wall-clock loop runs it: ``replan`` (x [nx], plan, key, n) -> (plan,
    info), its first warm start ``plan0`` (leaves [H, ...]) and ``shift(plan, steps) ->
    plan``, the host-side move of a plan ``steps`` ticks on (NumPy: nothing to compile
    while the clock runs)."""

    replan: Replan
    plan0: Any
    shift: Callable[[Any, int], Any]


class RealTimeResult(NamedTuple):
    """X [N+1, nx], U [N, nu]: the closed loop; stamps [N]: the stamp of the plan applied at
    each tick; replan_s [R]: the wall seconds of each of the R replans; late_ticks: ticks
    the plant began more than one period after they were due (the plant itself fell behind);
    wall_s: the loop's wall time."""

    X: np.ndarray
    U: np.ndarray
    stamps: np.ndarray
    replan_s: np.ndarray
    late_ticks: int
    wall_s: float


def native_plant(model: mujoco.MjModel, substeps: int) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """(x [nx], u [nu]) -> x after ``substeps`` native ``mj_step`` calls, float64; the state
    [qpos, qvel, act] (one MjData, reused: the plant is one thread's)."""
    data = mujoco.MjData(model)
    nq, nv = model.nq, model.nv

    def step(x: np.ndarray, u: np.ndarray) -> np.ndarray:
        data.qpos[:], data.qvel[:], data.act[:] = x[:nq], x[nq : nq + nv], x[nq + nv :]
        data.ctrl[:] = u
        for _ in range(substeps):
            mujoco.mj_step(model, data)
        return np.concatenate([data.qpos, data.qvel, data.act])

    return step


def moved_on(plan: Plan, steps: int) -> Plan:
    """A host plan [H, ...] moved ``steps`` ticks on (at most H), its last row repeated (the
    episode's shift, in NumPy: no program to compile while the clock runs)."""
    steps = min(steps, plan.U.shape[0])
    return type(plan)(*(np.concatenate([a[steps:], np.repeat(a[-1:], steps, axis=0)]) for a in plan))


def control(plan, j: int, x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """u = clip(U[j] + K[j] (x - X[j])) of a :class:`Plan` [H, ...] (host arrays), clip(U[j])
    of any other plan with controls U; its last row from j >= H on."""
    j = min(j, plan.U.shape[0] - 1)
    if not hasattr(plan, "K"):
        return np.clip(plan.U[j], lo, hi)
    return np.clip(plan.U[j] + plan.K[j] @ (x - plan.X[j]), lo, hi)


def lateness(stamps: np.ndarray, replan_every: int = 1) -> np.ndarray:
    """[N] ticks each tick's plan came later than the synchronous episode's schedule, where
    tick k applies the plan made at tick r floor(k / r) (r = ``replan_every``): 0 for a
    planner that keeps up, whatever r."""
    k = np.arange(len(stamps))
    return k // replan_every * replan_every - np.asarray(stamps)


def run(
    replan: Replan,
    plant_step: Callable[[np.ndarray, np.ndarray], np.ndarray],
    x0: np.ndarray,
    plan0: Plan,
    *,
    dt: float,
    steps: int,
    key: jax.Array,
    limits: tuple[np.ndarray, np.ndarray],
    process_noise: float = 0.0,
    speed: float = 1.0,
    clock: Callable[[], float] = time.perf_counter,
    stop: Callable[[], bool] | None = None,
    shift: Callable[[Any, int], Any] = moved_on,
    replan_every: int = 1,
) -> RealTimeResult:
    """``steps`` ticks of the plant on the wall clock (module docstring) under the plans of
    ``replan``, run in a second thread; ``plan0``: the first replan's warm start [H, ...]
    (a :class:`Plan`, or any plan with controls U and the host ``shift`` that moves it).
    Tick n's noise and a replan at n's key come from the n-th of ``steps`` keys split from
    ``key``, as in the synchronous episode (drawn before the clock starts): a planner that
    always ends before the next tick gives the episode's closed loop. ``replan_every`` = r:
    the planner replans from a measurement at least r ticks after its last one (the
    episode's ``replan_every``; ``mpc.replan_hz``), from the newest one. ``stop() -> True``
    (asked at every tick) ends the loop early: X and U then hold the ticks done."""
    if replan_every < 1:
        raise ValueError(f"replan_every: >= 1, got {replan_every}")
    x0 = np.asarray(x0, np.float64)
    halves = jax.vmap(jax.random.split)(jax.random.split(key, steps))  # [N, 2] keys
    W = process_noise * np.asarray(jax.vmap(lambda k: jax.random.normal(k, x0.shape))(halves[:, 1]))
    plan_keys = list(halves[:, 0])  # one array per tick, split before the clock starts: indexing
    # a key array while the clock runs is an operation of its own (0.9 ms of a 3 ms replan)
    lo, hi = (np.asarray(a, np.float64) for a in limits)

    def plan_at(x, warm, n):
        new, _ = replan(x, warm, plan_keys[n], np.int32(n))
        return jax.tree.map(lambda a: np.asarray(a, np.float64), jax.block_until_ready(new))

    plan0 = jax.tree.map(lambda a: np.asarray(a, np.float64), plan0)
    state = {"plan": plan_at(x0, plan0, 0), "stamp": 0, "x": x0, "n": 0, "done": False}
    ready = threading.Condition()
    replan_s: list[float] = []
    errors: list[BaseException] = []

    def planner():
        seen = 0
        try:
            while True:
                with ready:
                    ready.wait_for(lambda: state["done"] or state["n"] >= seen + replan_every)
                    if state["done"] or state["n"] >= steps:
                        return
                    x, n, plan, stamp = state["x"], state["n"], state["plan"], state["stamp"]
                seen = n
                t = time.perf_counter()
                new = plan_at(x, shift(plan, n - stamp), n)
                replan_s.append(time.perf_counter() - t)
                with ready:
                    state["plan"], state["stamp"] = new, n
        except BaseException as e:  # noqa: BLE001  (re-raised in the plant's thread)
            errors.append(e)

    worker = threading.Thread(target=planner, name="planner", daemon=True)
    X, U, stamps = [x0], [], []
    late = 0
    period = dt / speed
    worker.start()
    t0 = clock()
    try:
        for k in range(steps):
            wait = t0 + k * period - clock()
            if -wait > period:
                late += 1
            while wait > 0 and not (stop is not None and stop()):  # a stop is seen within 0.1 s
                time.sleep(min(wait, 0.1))
                wait = t0 + k * period - clock()
            if stop is not None and stop():
                break
            if errors:
                raise errors[0]
            with ready:
                plan, stamp = state["plan"], state["stamp"]
            u = control(plan, k - stamp, X[-1], lo, hi)
            x = plant_step(X[-1], u) + W[k]
            U.append(u)
            stamps.append(stamp)
            X.append(x)
            with ready:
                state["x"], state["n"] = x, k + 1
                ready.notify_all()
    finally:
        wall = clock() - t0
        with ready:
            state["done"] = True
            ready.notify_all()
        worker.join()
    return RealTimeResult(np.array(X), np.array(U), np.array(stamps), np.array(replan_s), late, wall)
