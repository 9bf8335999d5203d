"""What a run's largest arrays need, checked against this machine before anything is built
or compiled: the identification batch, the dense nx x nx arrays of a solve, and the
reduced-order scheme's arrays that grow as T nx (a grid of many cells).

Dense nx x nx float64 arrays: the task's Q and Q_f where they are matrices (a diagonal is
held as its diagonal, :func:`mjx_surrogate.tasks.quadratic`); for a full-order model, the
cost's Hessians l_xx [T+1, nx, nx] and the model's A [T, nx, nx]. A reduced model
(``sysid.scheme reduced``) builds none of the last two
(:func:`mjx_surrogate.control.local_model.projected_cost_derivatives`); the exact oracle is a
full-order solve, and where its arrays would not fit it is off by default.
"""

from __future__ import annotations

import os

import numpy as np

from mjx_surrogate.errors import ConfigError
from mjx_surrogate.identification.sysid import get_scheme
from mjx_surrogate.runs.config import Config
from mjx_surrogate.systems.registry import USER_FUNCTION
from mjx_surrogate.tasks import Task

GIB = 2**30
# float64 numbers of [T+1, nx] each the reduced scheme holds at its peak, per snapshot and
# control (the carried and the new basis V, the snapshots; the one-step samples run in chunks,
# sharding.vmap_in_chunks) and besides (the nominal, the line search's trials, the gains, the
# feedback trials): allen_cahn2d256 at T = 50 peaks at 4.4 GiB of resident memory against the
# 6.0 GiB these give (36 snapshots) (docs/performance.md, "PDEs")
REDUCED_PER_SAMPLE = 5
REDUCED_FIXED = 16


def machine_memory() -> int:
    """This machine's physical memory in bytes."""
    return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")


def check_identification_batch(cfg: Config, nx: int, nu: int, T: int, n_samples: int) -> None:
    """Reject horizons whose identification batch would not fit in memory (before compile)."""
    width = 2 * n_samples + cfg.solver.n_alphas * cfg.solver.n_starts
    bytes_ = 8 * 4 * T * width * (nx + nu)
    limit = 16 * GIB
    if bytes_ > limit:
        raise ConfigError(
            "task.T",
            f"T={T} needs about {bytes_ / GIB:.0f} GiB for one identification batch "
            f"({width} simulations per step); at most {limit / GIB:.0f} GiB: shorten the horizon "
            "or lower sysid.n_samples",
        )


def dense_arrays(task: Task, T: int, full_order: bool) -> int:
    """How many nx x nx float64 arrays a solve of horizon T holds (module docstring)."""
    weights = sum(int(np.ndim(W) == 2) for W in (task.Q, task.Q_f))
    return weights + (2 * T + 1 if full_order else 0)


def reduced_bytes(nx: int, nu: int, T: int, n: int) -> int:
    """The reduced scheme's arrays that grow as T nx, with n snapshots (its largest rank)."""
    return 8 * (T + 1) * nx * (REDUCED_PER_SAMPLE * (n + nu) + REDUCED_FIXED)


def solve_bytes(task: Task, nx: int, nu: int, T: int, full_order: bool, n: int) -> int:
    """What a D2C solve of horizon T needs of the arrays this module counts."""
    own = 0 if full_order else reduced_bytes(nx, nu, T, n)
    return 8 * nx * nx * dense_arrays(task, T, full_order) + own


def oracle_fits(task: Task, nx: int, nu: int) -> bool:
    """Whether the exact oracle's full-order solve fits in this machine's memory."""
    return solve_bytes(task, nx, nu, task.T, True, 0) <= machine_memory()


def oracle_off_reason(name: str, task: Task, nx: int, nu: int) -> str:
    """Why a run has no exact oracle: its full-order solve would not fit here (the default
    then), or the config (a user's MuJoCo model's default)."""
    if not oracle_fits(task, nx, nu):
        need = solve_bytes(task, nx, nu, task.T, True, 0) / GIB
        return (
            f"experiment.exact_oracle is off: the oracle's full-order solve (nx = {nx}) needs "
            f"{need:,.0f} GiB, more than this machine's {machine_memory() / GIB:.0f} GiB"
        )
    return "experiment.exact_oracle is false" + (" (a user model's default)" if name == "mjcf" else "")


def check_solve_memory(cfg: Config, system, task: Task, n_samples: int, oracle: bool) -> None:
    """Refuse a run whose D2C solve (and, with ``oracle``, the exact oracle's full-order
    solve) would not fit in this machine's memory, in one line: blamed on the system where
    even T = 1 does not fit, on ``task.T`` (with the longest horizon that does) where the
    task's does not, and on ``experiment.exact_oracle`` where only the oracle does not."""
    nx, nu, T, have = system.nx, system.nu, task.T, machine_memory()
    full = not get_scheme(cfg.sysid.scheme).reduced
    need = lambda T, full: solve_bytes(task, nx, nu, T, full, n_samples)  # noqa: E731
    if need(T, full) <= have:
        if oracle and need(T, True) > have:
            raise ConfigError(
                "experiment.exact_oracle",
                f"the exact oracle's full-order solve of {system.name!r} (nx = {nx}) needs "
                f"{need(T, True) / GIB:,.0f} GiB at T = {T}, more than this machine's {have / GIB:.0f} GiB; "
                "valid here: false",
            )
        return
    dense = (["the task's Q and Q_f"] if dense_arrays(task, 0, False) else []) + (
        ["the cost's Hessians", "the LTV model"] if full else []
    )
    what = f"its dense nx x nx arrays ({', '.join(dense)})" if dense else ""
    if not full:
        what += (
            " and " if dense else ""
        ) + "the reduced scheme's T x nx arrays (bases, snapshots, one-step samples)"
    short = need(1, full) > have
    said = (
        f"{system.name!r} has nx = {nx} states: {what} need {need(1 if short else T, full) / GIB:,.0f} GiB "
        f"{'at the shortest horizon, T = 1' if short else f'at T = {T}'}, more than this machine's "
        f"{have / GIB:.0f} GiB"
    )
    if short:
        field = "system.entry" if cfg.system.name == USER_FUNCTION else "system.name"
        raise ConfigError(field, f"{said}; valid here: nx <= {_largest_nx(task, nu, full, n_samples, have)}")
    lo, hi = 1, T  # the longest horizon that fits (need grows with T)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (mid, hi) if need(mid, full) <= have else (lo, mid)
    raise ConfigError("task.T", f"{said}; valid here: T <= {lo} for this system")


def _largest_nx(task: Task, nu: int, full: bool, n: int, have: int) -> int:
    """The largest nx whose solve fits at T = 1: a nx^2 + b nx <= have."""
    a = 8.0 * dense_arrays(task, 1, full)
    b = 0.0 if full else reduced_bytes(1, nu, 1, n)
    return int(have / b if a == 0 else (-b + (b * b + 4 * a * have) ** 0.5) / (2 * a))
