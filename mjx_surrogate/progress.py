"""Progress meters and stop requests for solvers running inside ``jax.jit``.

A :class:`ProgressMeter` is a small pytree passed to a solver as an argument (diffrax's
idea): its only leaf, ``meter_id``, is traced, so switching a meter on, off or to another
one never recompiles. Once per iteration the solver calls :func:`poll` from inside its
``lax.while_loop`` (one host callback, skipped by a ``lax.cond`` when the id is negative);
the host side advances the meter's bar, if it has one, and answers whether a stop was
requested (:func:`request_stop`, called by the CLI's SIGINT/SIGTERM handler). A solver
that is told to stop ends after the current iteration with ``StopReason.INTERRUPTED``
and returns its best iterate, so nothing it computed is lost.

    with progress.meter("D2C", total=100) as pm:
        result = solve_d2c(system, task, U0, key, progress=pm)

Any meter passed explicitly (``NO_PROGRESS`` included) shares one compiled program. A loop
driven from the host (:mod:`mjx_surrogate.control.chunked`) calls :func:`report` and
:func:`stop_polled` between its compiled chunks instead: no callback in the program.
"""

from __future__ import annotations

import contextlib
import itertools
import threading

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

_STOP = threading.Event()
_BARS: dict[int, object] = {}  # meter id -> tqdm bar (or None: poll for stops only)
_IDS = itertools.count()


@struct.dataclass
class ProgressMeter:
    """meter_id >= 0: report to that meter and poll for stop requests; < 0: do nothing."""

    meter_id: jax.Array


NO_PROGRESS = ProgressMeter(np.int32(-1))


def request_stop() -> None:
    """Ask every polling solver to stop after its current iteration, or chunk (signal-safe)."""
    _STOP.set()


def clear_stop() -> None:
    _STOP.clear()


def stop_requested() -> bool:
    _drain_wakeup()
    return _STOP.is_set()


@contextlib.contextmanager
def meter(desc: str, total: int, display: bool = True, leave: bool = True):
    """A meter for one solve: a tqdm bar when ``display`` (kept on screen when it ends if
    ``leave``), stop polling always."""
    i = next(_IDS)
    bar = None
    if display:
        from tqdm.auto import tqdm

        bar = tqdm(total=total, desc=desc, leave=leave, dynamic_ncols=True)
    _BARS[i] = bar
    try:
        yield ProgressMeter(np.int32(i))
    finally:
        _BARS.pop(i, None)
        if bar is not None:
            bar.close()


class Stopped(Exception):
    """A stop request seen between the steps of a host-driven stage (:func:`steps`)."""


class StepMeter:
    """What :func:`steps` yields: ``advance(label)`` before each step of a stage."""

    def __init__(self, bar, total: int):
        self._bar, self.total, self.done = bar, total, -1

    def advance(self, label: str) -> None:
        """Count the previous step as finished and show ``label`` as the running one;
        raises :class:`Stopped` if a stop was requested."""
        if stop_requested():
            raise Stopped(f"before {label!r}")
        self.done += 1
        if self._bar is not None:
            self._bar.n = self.done
            self._bar.set_postfix_str(label, refresh=False)
            self._bar.refresh()

    def extend(self, n: int) -> None:
        """``n`` more steps than announced (known only once earlier steps ran)."""
        self.total += n
        if self._bar is not None:
            self._bar.total = self.total
            self._bar.refresh()


@contextlib.contextmanager
def steps(desc: str, total: int, display: bool = True, tick_s: float = 1.0):
    """A meter for a stage made of ``total`` host-side steps (fits, trainings, sweeps):
    the bar names the running step and its clock is redrawn every ``tick_s`` seconds
    while a step runs, so a long compiled call shows that it is alive."""
    if not display:
        yield StepMeter(None, total)
        return
    from tqdm.auto import tqdm

    bar = tqdm(total=total, desc=desc, leave=True, dynamic_ncols=True)
    ticking = threading.Event()

    def tick():
        while not ticking.wait(tick_s):
            bar.refresh()

    thread = threading.Thread(target=tick, daemon=True, name="progress-tick")
    thread.start()
    meter_ = StepMeter(bar, total)
    try:
        yield meter_
        bar.n = total
    finally:
        ticking.set()
        thread.join()
        bar.close()


def _update_bar(meter_id: int, iteration, cost, mu) -> None:
    bar = _BARS.get(meter_id)
    if bar is None:
        return
    finite = np.asarray(cost)[np.isfinite(np.asarray(cost))]
    bar.n = int(np.max(np.asarray(iteration)))
    bar.set_postfix(
        J=f"{finite.min():.5g}" if finite.size else "inf",
        mu=f"{float(np.min(np.asarray(mu))):.1e}",
        refresh=False,
    )
    bar.refresh()


def _host_poll(meter_id, iteration, cost, mu) -> np.ndarray:
    """Host side: advance the bar (batched calls show the best cost), answer the stop flag."""
    _update_bar(int(np.atleast_1d(np.asarray(meter_id)).ravel()[0]), iteration, cost, mu)
    return np.full(np.shape(meter_id), stop_requested(), dtype=bool)


def displays(progress: ProgressMeter) -> bool:
    """Host side: whether ``progress`` shows a bar (a stage it starts can show one too)."""
    return _BARS.get(int(np.asarray(progress.meter_id))) is not None


def report(progress: ProgressMeter, iteration, cost, mu) -> None:
    """Host side, for a loop driven from the host (:mod:`mjx_surrogate.control.chunked`): advance
    ``progress``'s bar to ``iteration`` (cost and mu: the best of a batch)."""
    _update_bar(int(np.asarray(progress.meter_id)), iteration, cost, mu)


def stop_polled(progress: ProgressMeter) -> bool:
    """Host side: whether a stop was requested, for a meter that is on (False when off)."""
    return int(np.asarray(progress.meter_id)) >= 0 and stop_requested()


def poll(progress: ProgressMeter, iteration: jax.Array, cost: jax.Array, mu: jax.Array) -> jax.Array:
    """Traced: report one iteration to ``progress``; returns True if a stop was requested."""

    def call():
        out = jax.ShapeDtypeStruct((), jnp.bool_)
        return jax.pure_callback(
            _host_poll, out, progress.meter_id, iteration, cost, mu, vmap_method="expand_dims"
        )

    return jax.lax.cond(progress.meter_id >= 0, call, lambda: jnp.array(False))


def _host_step(meter_id, n) -> np.ndarray:
    """Host side of :func:`poll_step`: the bar shows n + 1 steps begun; the stop flag."""
    bar = _BARS.get(int(np.atleast_1d(np.asarray(meter_id)).ravel()[0]))
    if bar is not None:
        bar.n = int(np.max(np.asarray(n))) + 1
        bar.refresh()
    return np.full(np.shape(meter_id), stop_requested(), dtype=bool)


def poll_step(progress: ProgressMeter, n: jax.Array) -> jax.Array:
    """Traced: report that step ``n`` of a loop begins (an MPC episode's control steps);
    returns True if a stop was requested. With ``progress`` and ``n`` unbatched (a meter
    closed over by a ``vmap`` of episodes, the loop's own counter) the answer is one for
    the whole batch, so a ``lax.cond`` on it really skips the remaining steps."""

    def call():
        out = jax.ShapeDtypeStruct((), jnp.bool_)
        return jax.pure_callback(_host_step, out, progress.meter_id, n, vmap_method="expand_dims")

    return jax.lax.cond(progress.meter_id >= 0, call, lambda: jnp.array(False))


_WAKEUP: dict = {}
_WAKEUP_LOCK = threading.Lock()  # the pipe is read from several threads and closed by one


def _drain_wakeup() -> None:
    """A signal's C-level handler writes a byte to the wakeup pipe at once, even while the
    main thread is blocked inside XLA and its Python handler cannot run yet."""
    import os

    with _WAKEUP_LOCK:
        fd = _WAKEUP.get("read")
        if fd is None:
            return
        try:
            if os.read(fd, 64):
                _STOP.set()
        except (BlockingIOError, OSError):
            pass


STOP_GRACE_S = 3.0  # how long a stop request waits for the code to end by itself


def _watch(done: threading.Event, on_stuck, grace_s: float) -> None:
    """Watchdog thread: once a stop is requested (seen through the wakeup pipe even while
    the main thread is inside XLA), wait ``grace_s`` for the guarded block to end, else
    call ``on_stuck``."""
    while not done.is_set():
        _drain_wakeup()
        if _STOP.wait(0.1):
            break
    if not done.wait(grace_s):
        on_stuck()


@contextlib.contextmanager
def stop_on_signals(signals=None, on_stuck=None, grace_s: float = STOP_GRACE_S):
    """While active, SIGINT and SIGTERM request a stop (the solver ends after its current
    iteration, the run keeps what it finished); a second signal raises KeyboardInterrupt.
    ``on_stuck``: called from a watchdog thread when the block has not ended ``grace_s``
    after a stop request (code that polls for none: an XLA compile, a long jitted call);
    it is expected to save what it can and end the process. Main thread only; restores
    the previous handlers and wakeup fd on exit."""
    import os
    import signal

    signals = signals or (signal.SIGINT, signal.SIGTERM)
    r, w = os.pipe()
    os.set_blocking(r, False)
    os.set_blocking(w, False)
    previous = {s: signal.getsignal(s) for s in signals}
    received = []

    def handler(signum, frame):
        received.append(signum)
        if len(received) > 1:
            raise KeyboardInterrupt
        _STOP.set()

    old_fd = signal.set_wakeup_fd(w, warn_on_full_buffer=False)
    _WAKEUP["read"] = r
    for s in signals:
        signal.signal(s, handler)
    done = threading.Event()
    watchdog = None
    if on_stuck is not None:
        watchdog = threading.Thread(
            target=_watch, args=(done, on_stuck, grace_s), daemon=True, name="stop-watchdog"
        )
        watchdog.start()
    try:
        yield received
    finally:
        done.set()
        if watchdog is not None:  # ended before the caller goes on: no thread of ours at exit
            watchdog.join(timeout=1.0)
        for s, h in previous.items():
            signal.signal(s, h)
        signal.set_wakeup_fd(old_fd)
        with _WAKEUP_LOCK:
            _WAKEUP.pop("read", None)
            os.close(r)
            os.close(w)
