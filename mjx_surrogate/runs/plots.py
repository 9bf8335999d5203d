"""Figures (matplotlib, Agg). The only module of the library that imports matplotlib."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def state_fan(
    t: np.ndarray,
    X: np.ndarray,
    X_nominal: np.ndarray,
    labels: list[str],
    max_lines: int = 64,
    title: str = "",
):
    """Perturbed trajectories X [R, T+1, nx] around a nominal [T+1, nx], one panel per
    state coordinate (at most 6)."""
    n = min(X.shape[-1], 6)
    fig, axes = plt.subplots(1, n, figsize=(3.2 * n, 2.8), squeeze=False)
    for i, ax in enumerate(axes[0]):
        ax.plot(t, X[:max_lines, :, i].T, color="tab:blue", alpha=0.15, lw=0.8)
        ax.plot(t, X_nominal[:, i], color="k", lw=1.5, label="nominal")
        ax.set_xlabel("time [s]")
        ax.set_title(labels[i], fontsize=9)
    axes[0][0].legend(fontsize=8)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig


def _log_scale_if_positive(ax, values: list[np.ndarray]) -> None:
    """A log y axis when every finite value is positive; linear otherwise (a cost can be 0:
    a hold task started at an equilibrium)."""
    finite = np.concatenate([np.ravel(v)[np.isfinite(np.ravel(v))] for v in values] + [np.ones(1)])
    ax.set_yscale("log" if np.all(finite > 0) else "linear")


def cost_history(histories: dict[str, np.ndarray], title: str = ""):
    """Cost against iteration for each named solve (log scale where every cost is positive)."""
    fig, ax = plt.subplots(figsize=(5, 3.4))
    for name, h in histories.items():
        h = np.asarray(h)
        ax.plot(np.arange(len(h)), h, marker="o", ms=3, label=name)
    _log_scale_if_positive(ax, [np.asarray(h, float) for h in histories.values()])
    ax.set_xlabel("iteration")
    ax.set_ylabel("cost J on the black box")
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def trajectory_evolution(
    t: np.ndarray,
    X_iters: np.ndarray,
    x_goal: np.ndarray,
    labels: list[str],
    title: str = "",
    indices: list[int] | None = None,
):
    """Nominal trajectories X_iters [K, T+1, nx] over iterations, light to dark, for the
    state coordinates ``indices`` (default: the first 4), four panels a row."""
    idx = list(indices) if indices is not None else list(range(min(X_iters.shape[-1], 4)))
    cols = min(len(idx), 4)
    rows = -(-len(idx) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.3 * cols, 2.7 * rows), squeeze=False)
    K = X_iters.shape[0]
    colors = plt.cm.viridis(np.linspace(0.1, 0.95, K))
    for ax in axes.flat[len(idx) :]:
        ax.set_visible(False)
    for i, ax in zip(idx, axes.flat):
        for k in range(K):
            ax.plot(t, X_iters[k, :, i], color=colors[k], lw=1.0 if k < K - 1 else 2.0)
        ax.axhline(x_goal[i], color="r", ls="--", lw=0.8)
        ax.set_title(labels[i], fontsize=9)
        ax.set_xlabel("time [s]")
    legend = "purple: early iterations, yellow: final" if K > 1 else "the final iterate only"
    fig.suptitle(f"{title} ({legend}; red dashed: goal)", fontsize=10)
    fig.tight_layout()
    return fig


def cost_vs_noise(
    noise: np.ndarray,
    costs: dict[str, np.ndarray],
    title: str = "",
    xlabel: str = "control noise std (fraction of U_max: the actuator limit, else max |u*|)",
):
    """Median and 10-90 % band of closed-loop / open-loop cost [L, N] against noise [L], over
    the finite draws (a level without any is left out)."""
    fig, ax = plt.subplots(figsize=(5, 3.4))
    for name, c in costs.items():
        c = np.asarray(c, float)
        finite = np.isfinite(c)
        q = np.full((3, c.shape[0]), np.nan)
        for i in np.nonzero(finite.any(axis=1))[0]:
            q[:, i] = np.percentile(c[i][finite[i]], [50, 10, 90])
        med, lo, hi = q
        ax.plot(noise, med, marker="o", label=name)
        ax.fill_between(noise, lo, hi, alpha=0.2)
    if any(np.isfinite(np.asarray(c, float)).any() for c in costs.values()):
        ax.set_yscale("log")
    else:
        ax.text(0.5, 0.5, "no finite cost at any noise level", ha="center", transform=ax.transAxes)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("cost J")
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def predictions(
    t: np.ndarray,
    true: np.ndarray,
    preds: dict[str, np.ndarray],
    coords: list[int],
    labels: list[str],
    phase: tuple[int, int] | None = None,
    title: str = "",
    reference_label: str = "black box",
):
    """Open-loop predictions against the black box along one trajectory.

    true [T+1, nx]; preds name -> [T+1, nx]; one panel per state coordinate in coords,
    plus a phase portrait (q, qdot) when phase = (i, j) is given. Diverged predictions are
    clipped to 3x the true range so the panels stay readable.
    """
    n = len(coords) + (phase is not None)
    fig, axes = plt.subplots(1, n, figsize=(3.6 * n, 3.2), squeeze=False)
    axes = axes[0]

    def clip(a, c):
        lo, hi = np.nanmin(true[:, c]), np.nanmax(true[:, c])
        pad = 3 * max(hi - lo, 1e-6)
        return np.clip(a, lo - pad, hi + pad)

    for ax, c in zip(axes, coords):
        ax.plot(t, true[:, c], "k", lw=2.2, label=reference_label)
        for name, p in preds.items():
            ax.plot(t, clip(p[:, c], c), lw=1.2, label=name)
        ax.set_xlabel("t (s)")
        ax.set_ylabel(labels[c])
        ax.grid(alpha=0.3)
    if phase is not None:
        i, j = phase
        ax = axes[-1]
        ax.plot(true[:, i], true[:, j], "k", lw=2.2, label=reference_label)
        for name, p in preds.items():
            ax.plot(clip(p[:, i], i), clip(p[:, j], j), lw=1.2, label=name)
        ax.set_xlabel(labels[i])
        ax.set_ylabel(labels[j])
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig


def error_vs_level(
    levels: np.ndarray,
    errors: dict[str, np.ndarray],
    ylabel: str,
    title: str = "",
    ranges: dict[str, np.ndarray] | None = None,
):
    """Prediction error of each model against the perturbation level (log scale); where
    ``ranges[name]`` [2, n_levels] is given (the least and largest over data sets), a band."""
    fig, ax = plt.subplots(figsize=(5, 3.4))
    x = 100 * np.asarray(levels)
    for name, e in errors.items():
        e = np.asarray(e, float)
        e = np.where(np.isfinite(e), e, np.nan)
        (line,) = ax.plot(x, e, marker="o", label=name)
        if ranges is not None and name in ranges:
            lo, hi = (np.where(np.isfinite(r), r, np.nan) for r in np.asarray(ranges[name], float))
            ax.fill_between(x, lo, hi, color=line.get_color(), alpha=0.15, lw=0)
    ax.set_yscale("log")
    ax.set_xlabel("control perturbation (% of U_max)")
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    return fig


def locality(levels: np.ndarray, spread: np.ndarray, gain: float, title: str = ""):
    """The data sets' relative spread around the optimum against the level (log scale),
    with 1 (as far off as the whole manoeuvre) marked."""
    fig, ax = plt.subplots(figsize=(5, 3.4))
    s = np.asarray(spread, float)
    s = np.where(np.isfinite(s), s, np.nan)
    ax.plot(100 * np.asarray(levels), s, marker="o", label="median relative spread")
    ax.axhline(1.0, color="k", lw=0.8, ls="--", label="= the optimum's own excursion")
    ax.set_yscale("log")
    ax.set_xlabel("control perturbation (% of U_max)")
    ax.set_ylabel("max_t |x - x*| / max_t |x* - x*_0|")
    ax.set_title(f"{title}\nopen-loop gain of the optimum: {gain:.3g}", fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    return fig


def theory_curves(orders: np.ndarray, curves: dict[str, list[float]], ylabel: str, title: str = ""):
    """Quantities against the basis order N, log scale; 'exact' solid, 'paper' dashed,
    'Monte Carlo' as markers, one colour per basis."""
    fig, ax = plt.subplots(figsize=(5.4, 3.8))
    colours: dict[str, str] = {}
    for name, vals in curves.items():
        base = name.split(" ")[0].rstrip(",")
        c = colours.setdefault(base, f"C{len(colours)}")
        v = np.asarray(vals, float)
        v = np.where(v > 0, v, np.nan)
        if "paper" in name:
            ax.plot(orders, v, "--", color=c, label=name)
        elif "Monte Carlo" in name:
            ax.plot(orders, v, "o", color=c, ms=4, mfc="none", label=name)
        else:
            ax.plot(orders, v, "-", color=c, label=name)
    ax.set_yscale("log")
    ax.set_xlabel("basis order N")
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=6.5, ncol=2)
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    return fig


def seed_overlay(
    t: np.ndarray, X_true: np.ndarray, P: np.ndarray, coords: list[int], labels: list[str], title: str = ""
):
    """Predictions of K models P [K, T+1, nx] (one per data set) over the true trajectory."""
    return predictions(t, X_true, {f"seed {k}": P[k] for k in range(P.shape[0])}, coords, labels, None, title)


def spectra(svals: dict[str, np.ndarray], title: str = ""):
    """Sorted singular values (square roots of Gram eigenvalues), normalised by the largest."""
    fig, ax = plt.subplots(figsize=(5.4, 3.6))
    for name, s in svals.items():
        s = np.asarray(s, float)
        ax.plot(np.arange(1, s.size + 1) / s.size, s / s[0], label=f"{name} (n={s.size})")
    ax.set_yscale("log")
    ax.set_xlabel("index / number of columns")
    ax.set_ylabel("singular value / largest")
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    return fig


def projections(
    proj: dict[str, np.ndarray],
    xlabel: str = "basis function index",
    ylabel: str = "(1/R) Theta' (y - Theta C)",
):
    """Vectors per data set, one line each: name -> [S, P] (error projections on the basis,
    or the MLP's descent directions)."""
    fig, axes = plt.subplots(1, len(proj), figsize=(4.6 * len(proj), 3.2), squeeze=False)
    for ax, (name, D) in zip(axes[0], proj.items()):
        for s in range(D.shape[0]):
            ax.plot(np.arange(D.shape[1]), D[s], lw=1, marker=".", ms=3, label=f"data set {s}")
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.set_title(name, fontsize=9)
        ax.grid(alpha=0.3)
    axes[0][0].legend(fontsize=7)
    fig.tight_layout()
    return fig


def cost_vs_simulations(curves: dict[str, tuple[np.ndarray, np.ndarray]], title: str = ""):
    """Cost after each iteration against the black-box control steps simulated so far."""
    fig, ax = plt.subplots(figsize=(5, 3.4))
    for label, (steps, cost) in curves.items():
        ax.plot(steps, cost, marker=".", label=label)
    _log_scale_if_positive(ax, [np.asarray(cost, float) for _, cost in curves.values()])
    ax.set_xlabel("simulated control steps")
    ax.set_ylabel("cost J")
    ax.set_title(title, fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def cost_vs_calls(points: dict[str, list[tuple[float | None, float | None]]], title: str = ""):
    """Closed-loop cost against black-box control steps per control step, one marker per
    (controller, condition); controllers whose calls are not counted (None) are left out."""
    fig, ax = plt.subplots(figsize=(5.6, 3.6))
    for label, pts in points.items():
        pts = [(c, j) for c, j in pts if c is not None and j is not None]
        if pts:
            ax.scatter(*zip(*pts), label=label, s=22)
    ax.set_xscale("symlog", linthresh=1.0)
    ax.set_yscale("log")
    ax.set_xlabel("black-box control steps per control step (0: the plant's only)")
    ax.set_ylabel("closed-loop cost (median over episodes)")
    ax.set_title(title, fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def horizon_errors(
    t: np.ndarray,
    errors: dict[str, np.ndarray],
    cl_errors: dict[str, np.ndarray],
    spreads: dict[str, np.ndarray],
    title: str = "",
):
    """Against t: the relative error of the identified [A_t B_t], of A_t + B_t K_t, and the
    rollouts' median relative deviation from the nominal. Open loop dashed, closed solid."""
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.6))
    for ax, curves, ts, ylabel in (
        (axes[0], errors, t[:-1], "||[A B] - [A* B*]||_F / ||[A* B*]||_F"),
        (axes[1], cl_errors, t[:-1], "||(A + B K) - (A* + B* K)||_F / ||A* + B* K||_F"),
        (axes[2], spreads, t, "median ||x_t - X_t|| / RMS ||X||"),
    ):
        colours: dict[str, str] = {}
        for name, v in curves.items():
            level = name.split(", ")[-1]
            c = colours.setdefault(level, f"C{len(colours)}")
            v = np.where(np.isfinite(np.asarray(v, float)) & (np.asarray(v, float) > 0), v, np.nan)
            ax.plot(ts, v, "--" if name.startswith("open") else "-", color=c, label=name)
        ax.set_yscale("log")
        ax.set_xlabel("time step t (rollout length)")
        ax.set_ylabel(ylabel, fontsize=8)
        ax.grid(alpha=0.3, which="both")
    axes[0].legend(fontsize=7)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig
