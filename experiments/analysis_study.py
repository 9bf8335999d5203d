"""Experiment kind "analysis": the paper's model-convergence, ill-conditioning and variance
experiments around the task's optimum (paper: the cartpole swing-up).

Stages: ``optimum``, ``convergence``, ``ill_conditioning``, ``variance``, ``ltv`` (each drives
a step meter naming the fit or training it runs), each figure drawn once its stage is written.
"""

from __future__ import annotations

import time
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from mjx_surrogate import progress
from mjx_surrogate.analysis import ltv_sampling, spectra
from mjx_surrogate.identification import data, step_models
from mjx_surrogate.linalg import unit_diagonal
from mjx_surrogate.runs import pipeline, plots
from mjx_surrogate.runs.config import Config
from mjx_surrogate.runs.experiment_kinds import analysis_library_specs
from mjx_surrogate.runs.resolution import Resolved, solver_params
from mjx_surrogate.runs.results import Run
from mjx_surrogate.sharding import on_one_device
from mjx_surrogate.surrogates import mlp, sindy
from mjx_surrogate.surrogates.registry import library_specs, mlp_spec
from mjx_surrogate.systems.black_box import BlackBox
from mjx_surrogate.tasks import Task


def _datasets(system, task, X_star, U_star, key, cfg, level):
    """K data sets from one sampling distribution: (train list, test list) of Transitions."""
    keys = jax.random.split(key, cfg.analysis.n_datasets)
    lim = (task.u_min, task.u_max)
    sets = data.sample_seeds(system, X_star, U_star, keys, cfg.data.n_traj, level, cfg.data.x0_sigma, *lim)
    out = []
    for i in range(cfg.analysis.n_datasets):
        ds = data.Dataset(sets.X[i], sets.U[i])
        train, test = data.split(ds, jax.random.fold_in(key, i), cfg.data.test_fraction)
        out.append((data.transitions(train), data.transitions(test)))
    return out


def _common(trs: list, m: int | None = None):
    """Stack transitions of K data sets, truncated to the smallest size (for vmap)."""
    m = m or min(t.x.shape[0] for t in trs)
    z = jnp.stack([jnp.concatenate([t.x[:m], t.u[:m]], -1) for t in trs])
    xn = jnp.stack([t.x_next[:m] for t in trs])
    return z, xn


def _spread(P: np.ndarray) -> float:
    """Mean over time and coordinates of the std across seeds of predictions P [K, T+1, nx]."""
    return float(np.nanmean(np.nanstd(P, axis=0))) if np.isfinite(P).any() else float("inf")


def spread_interval(P: np.ndarray, key: jax.Array, n_boot: int = 1000) -> list[float]:
    """A 90 % bootstrap interval of :func:`_spread` over the K data sets of P [K, T+1, nx]
    (resampled with replacement; draws from ``key``). Each resample's std is taken with
    ddof 1: a resample of the K predictions has E[s*^2 (ddof 1)] = the estimate's variance
    (ddof 0), so the interval is centred on it (with ddof 0 it sits (K-1)/K low)."""
    if not np.isfinite(P).any():
        return [float("inf"), float("inf")]
    K = P.shape[0]
    idx = np.asarray(jax.random.randint(key, (n_boot, K), 0, K))
    boot = np.array([np.nanmean(np.nanstd(P[i], axis=0, ddof=1)) for i in idx])
    return [float(np.quantile(boot, 0.05)), float(np.quantile(boot, 0.95))]


class _Study(NamedTuple):
    """What every stage of the study needs: the config, system and task, the optimum X_star
    [T+1, nx], U_star [T, nu], the libraries, the MLP's spec, a key per stage."""

    cfg: Config
    system: BlackBox
    task: Task
    X_star: jax.Array
    U_star: jax.Array
    specs: dict
    spec_mlp: mlp.MLPSpec
    keys: dict


def run(res: Resolved, record: Run, key: jax.Array) -> str:
    cfg, system, task = res
    keys = dict(zip(("opt", "conv", "gram", "var"), jax.random.split(key, 4)))
    record.add_arrays({"x0": task.x0})
    m_opt, a_opt = record.stage("optimum", pipeline.optimum_stage(res, keys["opt"]))
    if m_opt["cost"] is None:
        return "diverged"
    X_star, U_star = jnp.asarray(a_opt["X_star"]), jnp.asarray(a_opt["U_star"])
    specs = library_specs(cfg, system) | analysis_library_specs(cfg, system)
    s = _Study(cfg, system, task, X_star, U_star, specs, mlp_spec(cfg), keys)
    _, a_conv = record.stage("convergence", lambda: _convergence(s))
    _convergence_figures(record, s, a_conv)
    _, a_gram = record.stage("ill_conditioning", lambda: _ill_conditioning(s))
    _gram_figure(record, s, a_gram)
    _, a_var = record.stage("variance", lambda: _variance(s))
    _variance_figures(record, s, a_var)
    record.stage("ltv", lambda: _ltv(s))
    record.folder.write_text("analysis_table.md", _table(record.metrics))
    return m_opt["status"]


def _convergence(s: _Study) -> tuple[dict, dict]:
    """1. Model convergence across data sets: each model's open-loop prediction of the
    optimal controls, trained on ``n_datasets`` data sets per level."""
    a = s.cfg.analysis
    conv, arrays = {}, {}
    x0, U1 = s.X_star[0][None], s.U_star[None]
    scale = float(np.sqrt(np.mean(np.asarray(s.X_star) ** 2)))  # the RMS state along the optimum
    runs = [
        *(("SINDy", lv, j) for j, lv in enumerate(a.convergence_sindy_levels)),
        *(("MLP", lv, j) for j, lv in enumerate(a.convergence_mlp_levels)),
    ]
    with progress.steps("analysis: model convergence", len(runs), s.cfg.experiment.progress) as meter:
        for kind, level, j in runs:
            meter.advance(f"{kind} {100 * level:g}%: {a.n_datasets} data sets")
            k = jax.random.fold_in(s.keys["conv"], 100 * j + len(kind))
            sets = _datasets(s.system, s.task, s.X_star, s.U_star, k, s.cfg, level)
            steps, extra = _sindy_fits(s, sets) if kind == "SINDy" else _mlp_fits(s, sets, j)
            P = np.stack(
                [np.asarray(step_models.predict(step_models.time_invariant(f), x0, U1))[0] for f in steps]
            )
            spread, interval = _spread(P), spread_interval(P, jax.random.fold_in(k, 1))
            conv[f"{kind} {100 * level:g}%"] = {
                "prediction_spread": spread,
                "relative_spread": spread / scale,  # of the RMS state along the optimum
                "relative_spread_interval": [v / scale for v in interval],  # 90 %, over the data sets
                **extra,
                "final_state_spread": np.nanstd(P[:, -1], axis=0).tolist(),
            }
            arrays[f"convergence_{kind}_{level:g}"] = P
    return conv, arrays


def _sindy_fits(s: _Study, sets: list) -> tuple[list, dict]:
    """One SINDy fit per data set: their steps, and the coefficients' relative spread."""
    sc = s.cfg.surrogate
    spec = s.specs[s.cfg.analysis.convergence_library]
    fits = [
        sindy.fit(spec, *on_one_device(tr.x, tr.u, tr.x_next), increment=sc.increment, method=sc.sindy.method)
        for tr, _ in sets
    ]
    C = np.stack([np.asarray(m.coef) for m in fits])
    return [m.step for m in fits], {
        "coef_rel_std": float(np.mean(C.std(0)) / max(np.mean(np.abs(C.mean(0))), 1e-300))
    }


def _mlp_fits(s: _Study, sets: list, j: int) -> tuple[list, dict]:
    """One network per data set, trained together: their steps, and how long they trained."""
    nx, spec_mlp, n = s.system.nx, s.spec_mlp, s.cfg.analysis.n_datasets
    z, xn = _common([tr for tr, _ in sets])
    zt, xnt = _common([te for _, te in sets])
    y = mlp.targets(z[..., :nx], xn, spec_mlp.increment)
    yt = mlp.targets(zt[..., :nx], xnt, spec_mlp.increment)
    kk = jax.random.split(jax.random.fold_in(s.keys["conv"], 7 + j), n)
    t0 = time.perf_counter()
    trained = jax.block_until_ready(mlp.train_seeds(spec_mlp, kk, z, y, zt, yt, mesh=s.system.mesh))
    steps = [mlp.unstack(trained, i).model.step for i in range(n)]
    return steps, _training(trained, time.perf_counter() - t0)


def _convergence_figures(record: Run, s: _Study, a_conv: dict) -> None:
    a, system = s.cfg.analysis, s.system
    t = np.arange(s.task.T + 1) * system.dt
    coords = list(range(min(system.nq, 2)))
    for kind, levels in (("SINDy", a.convergence_sindy_levels), ("MLP", a.convergence_mlp_levels)):
        for level in levels:
            record.figure(
                f"convergence_{kind.lower()}_{100 * level:g}pct.png",
                lambda: plots.seed_overlay(
                    t,
                    np.asarray(s.X_star),
                    a_conv[f"convergence_{kind}_{level:g}"],
                    coords,
                    list(system.state_labels),
                    f"{kind} trained on {a.n_datasets} data sets, {100 * level:g}% U_max: optimal controls",
                ),
            )


def _ill_conditioning(s: _Study) -> tuple[dict, dict]:
    """2. Gram spectra: SINDy's design Gram per library, the MLP's Jacobian Gram per level."""
    a, system, cfg = s.cfg.analysis, s.system, s.cfg
    gram, arrays = {}, {}
    n = len(a.gram_libraries) + len(a.gram_mlp_levels)
    with progress.steps("analysis: Gram spectra", n, cfg.experiment.progress) as meter:
        ((tr, _),) = _datasets(
            system, s.task, s.X_star, s.U_star, s.keys["gram"], _one(cfg), a.gram_sindy_level
        )
        for name in a.gram_libraries:
            meter.advance(f"SINDy {name}")
            theta = sindy.design(s.specs[name], tr.x, tr.u)
            G = np.asarray(sindy.gram(theta), np.float64)
            eig = spectra.eigenvalues(G)
            scaled = unit_diagonal(G[None])[0][0]  # as the LTV solver scales its Gram
            gram[f"SINDy {name} {100 * a.gram_sindy_level:g}%"] = {
                "condition": spectra.condition(eig),
                "condition_unit_diagonal": spectra.condition(spectra.eigenvalues(scaled)),
                "n_features": int(theta.shape[1]),
                "precision": str(theta.dtype),
            }
            arrays[f"sindy_gram_eigs_{name}"] = eig
        for j, level in enumerate(a.gram_mlp_levels):
            meter.advance(f"MLP {100 * level:g}%: training, Jacobian Gram")
            gram[f"MLP {100 * level:g}%"], arrays[f"mlp_gram_eigs_{level:g}"] = _mlp_gram(s, j, level)
    return gram, arrays


def _mlp_gram(s: _Study, j: int, level: float) -> tuple[dict, np.ndarray]:
    """One network trained at ``level``: its Jacobian Gram's spectrum on gram_points inputs."""
    a, spec_mlp, key = s.cfg.analysis, s.spec_mlp, s.keys["gram"]
    ((tr, te),) = _datasets(
        s.system, s.task, s.X_star, s.U_star, jax.random.fold_in(key, j + 1), _one(s.cfg), level
    )
    z = jnp.concatenate([tr.x, tr.u], -1)
    zt = jnp.concatenate([te.x, te.u], -1)
    r = mlp.train(
        spec_mlp,
        jax.random.fold_in(key, 50 + j),
        z,
        mlp.targets(tr.x, tr.x_next, spec_mlp.increment),
        zt,
        mlp.targets(te.x, te.x_next, spec_mlp.increment),
    )
    zs, _ = spectra.standardise(r.model, z[: a.gram_points], z[: a.gram_points, : s.system.nx])
    G = spectra.mlp_gram(r.model, zs)
    eig = spectra.eigenvalues(G)
    tol = spectra.gram_rank_tolerance(zs.shape[0] * s.system.nx, eig.size, G.dtype)
    rank, cond_rest = spectra.rank_and_condition(eig, tol)
    hidden = sum(spec_mlp.widths)  # one scaling symmetry per ReLU unit: an exact null direction each
    return {
        "condition": spectra.condition(eig),
        "n_params": int(eig.size),
        "eigenvalues_below_1e-12_of_max": int(np.sum(eig < 1e-12 * eig[0])),
        "null_space": int(eig.size - rank),  # eigenvalues below tol: the Gram's numerical null space
        "hidden_unit_symmetries": hidden,
        "rank_tolerance": tol,
        "condition_of_the_rest": cond_rest,  # apart from the null space (spectra.rank_and_condition)
        "precision": f"{G.dtype} Gram of {G.dtype} Jacobians at the trained (float32) parameters",
    }, eig


def _gram_figure(record: Run, s: _Study, a_gram: dict) -> None:
    a = s.cfg.analysis
    spectra_plot = {f"SINDy {n}": np.sqrt(a_gram[f"sindy_gram_eigs_{n}"]) for n in a.gram_libraries}
    spectra_plot |= {
        f"MLP {100 * lv:g}%": np.sqrt(a_gram[f"mlp_gram_eigs_{lv:g}"]) for lv in a.gram_mlp_levels
    }  # singular values of Theta / sqrt(R)
    record.figure("gram_spectra.png", lambda: plots.spectra(spectra_plot, "Gram matrix spectra"))


def pooled_projections(thetas: list, ys: list, method: str) -> tuple[np.ndarray, np.ndarray]:
    """Each data set's error projections against the fit on all of them pooled, D [S, P, nx],
    and its normal equations' right-hand side [S, P, nx], from designs Theta_s [R_s, P] and
    targets Y_s [R_s, nx]. The data sets are gathered on one device first, where the pooled
    fit solves: rows spread over CPU devices and a coefficient on one do not meet in one
    program."""
    thetas, ys = list(on_one_device(*thetas)), list(on_one_device(*ys))
    pooled = sindy.lstsq(jnp.concatenate(thetas), jnp.concatenate(ys), method)
    D = np.asarray(spectra.error_projections(thetas, ys, pooled))
    return D, np.asarray(jnp.stack([sindy.projections(th, y) for th, y in zip(thetas, ys)]))


def _variance(s: _Study) -> tuple[dict, dict]:
    """3. Variance of the error projections across data sets (SINDy), and the MLP's descent
    directions across data sets."""
    a, cfg, system = s.cfg.analysis, s.cfg, s.system
    var, arrays = {}, {}
    with progress.steps(
        "analysis: variance", len(a.variance_libraries) + 1, cfg.experiment.progress
    ) as meter:
        for j, (name, level) in enumerate(zip(a.variance_libraries, a.variance_levels)):
            meter.advance(f"SINDy {name} {100 * level:g}%: {a.n_datasets} data sets")
            key = jax.random.fold_in(s.keys["var"], j)
            sets = _datasets(system, s.task, s.X_star, s.U_star, key, cfg, level)
            thetas = [sindy.design(s.specs[name], tr.x, tr.u) for tr, _ in sets]
            ys = [tr.x_next - tr.x if cfg.surrogate.increment else tr.x_next for tr, _ in sets]
            D, rhs = pooled_projections(thetas, ys, cfg.surrogate.sindy.method)
            var[f"SINDy {name} {100 * level:g}%"] = {
                "projection_std_mean": float(D.std(0).mean()),
                "relative_to_rhs": float(D.std(0).mean() / np.abs(rhs.mean(0)).mean()),
                "n_features": int(D.shape[1]),
            }
            arrays[f"variance_projections_{name}_{level:g}"] = D
        meter.advance(f"MLP {100 * a.gram_mlp_levels[0]:g}%: descent directions, {a.n_datasets} data sets")
        var.update(
            _mlp_directions(cfg, system, s.task, s.X_star, s.U_star, s.keys["var"], s.spec_mlp, arrays)
        )
    return var, arrays


def _variance_figures(record: Run, s: _Study, a_var: dict) -> None:
    a = s.cfg.analysis
    level = a.gram_mlp_levels[0]
    dirs = {}
    for when in ("epoch0", "trained"):
        G = a_var[f"mlp_descent_directions_{when}"]
        dirs[f"MLP {100 * level:g}%, {when}: (1/R) H' Delta"] = G[:, :200] / np.linalg.norm(
            G, axis=1, keepdims=True
        )
    record.figure(
        "mlp_descent_directions.png",
        lambda: plots.projections(dirs, "parameter index (first 200)", "unit descent direction"),
    )
    proj_plot = {
        f"SINDy {n} {100 * lv:g}%": a_var[f"variance_projections_{n}_{lv:g}"][..., 1 % s.system.nx]
        for n, lv in zip(a.variance_libraries, a.variance_levels)
    }  # a velocity-like equation
    record.figure("variance_projections.png", lambda: plots.projections(proj_plot))


def _mlp_directions(cfg, system, task, X_star, U_star, key, spec_mlp, arrays) -> dict:
    """(1/R) H' Delta before training and once trained: K networks with the same initial
    weights and batches on K data sets, and the same-data control, K networks whose training
    seeds differ on the first data set (what the seed alone moves)."""
    a = cfg.analysis
    level = a.gram_mlp_levels[0]
    K = a.n_datasets
    sets = _datasets(system, task, X_star, U_star, jax.random.fold_in(key, 99), cfg, level)
    z, xn = _common([tr for tr, _ in sets])
    y = mlp.targets(z[..., : system.nx], xn, spec_mlp.increment)
    spec = spec_mlp._replace(checkpoints=(0,))
    zt, xnt = _common([te for _, te in sets])
    yt = mlp.targets(zt[..., : system.nx], xnt, spec_mlp.increment)
    first = [jnp.broadcast_to(v[:1], v.shape) for v in (z, y, zt, yt)]  # data set 0, K times
    arms = {
        "data sets": (jnp.stack([jax.random.fold_in(key, 5)] * K), z, y, zt, yt),
        "same data": (jax.random.split(jax.random.fold_in(key, 6), K), *first),
    }
    out, G = {}, {}
    for arm, (keys, za, ya, zta, yta) in arms.items():
        t0 = time.perf_counter()
        trained = jax.block_until_ready(mlp.train_seeds(spec, keys, za, ya, zta, yta, mesh=system.mesh))
        if arm == "data sets":
            out["_mlp_training"] = _training(trained, time.perf_counter() - t0)
        for when in ("epoch0", "trained"):
            rows = []
            for i in range(K):
                r = mlp.unstack(trained, i)
                model = r.model
                if when == "epoch0":
                    model = model.replace(params=jax.tree.map(lambda p: p[0], r.checkpoints))
                zs, ys = spectra.standardise(model, za[i, : a.gram_points], ya[i, : a.gram_points])
                rows.append(np.asarray(spectra.mlp_descent_direction(model, zs, ys)))
            G[arm, when] = np.stack(rows)
    rng = np.random.default_rng(int(jax.random.randint(jax.random.fold_in(key, 7), (), 0, 2**31 - 1)))
    for when in ("epoch0", "trained"):
        D, C = G["data sets", when], G["same data", when]
        out[f"MLP {100 * level:g}% {'epoch 0' if when == 'epoch0' else 'trained'}"] = {
            "mean_pairwise_cosine": spectra.mean_pairwise_cosine(D),
            "mean_pairwise_cosine_interval": spectra.pairwise_cosine_interval(D, rng),
            "min_pairwise_cosine": float(spectra.pairwise_cosines(D).min()),
            "same_data_cosine": spectra.mean_pairwise_cosine(C),
            "same_data_cosine_interval": spectra.pairwise_cosine_interval(C, rng),
        }
        arrays[f"mlp_descent_directions_{when}"] = D
        arrays[f"mlp_descent_directions_{when}_same_data"] = C
    return out


def _training(trained, seconds: float) -> dict:
    """Epochs, final losses and wall time of K networks trained together."""
    n = np.asarray(trained.epochs_run)
    te = np.asarray(trained.test_loss)
    return {
        "epochs": n.tolist(),
        "final_test_loss": [float(te[i, k - 1]) for i, k in enumerate(n)],
        "train_s": seconds,
    }


def _ltv(s: _Study) -> tuple[dict, dict]:
    """4. The local LTV regression's Gram, variance and accuracy under each sampling
    distribution (:mod:`mjx_surrogate.analysis.ltv_sampling`), at the solver's sample count and spread."""
    _, p = solver_params(s.cfg)
    with progress.steps("analysis: LTV regression", 1, s.cfg.experiment.progress) as meter:
        kinds = ltv_sampling.distributions(p.n_samples, s.system.nx, s.system.nu)
        meter.advance(f"{len(kinds)} distributions x {s.cfg.analysis.n_datasets} seeds")
        key = jax.random.fold_in(s.keys["var"], 1000)
        n = s.cfg.analysis.n_datasets
        return ltv_sampling.measure(s.system, s.X_star, s.U_star, key, n, p.n_samples, p.sigma_x, p.sigma_u)


def _one(cfg):
    import dataclasses

    return dataclasses.replace(cfg, analysis=dataclasses.replace(cfg.analysis, n_datasets=1))


def _table(m: dict) -> str:
    lines = [
        "## Model convergence across data sets (optimal controls from the optimal start)\n",
        "| model | prediction spread (mean std across seeds) |",
        "|---|---|",
    ]
    lines += [f"| {k} | {v['prediction_spread']:.3g} |" for k, v in m["convergence"].items()]
    lines += ["\n## Gram-matrix conditioning\n", "| model | condition number | precision |", "|---|---|---|"]
    lines += [f"| {k} | {v['condition']:.3g} | {v['precision']} |" for k, v in m["ill_conditioning"].items()]
    lines += ["\n## Variance across data sets\n", "| quantity | value |", "|---|---|"]
    for k, v in m["variance"].items():
        if not k.startswith("_"):
            lines += [f"| {k}: {q} | {_g(x)} |" for q, x in v.items()]
    ltv = {k: v for k, v in (m.get("ltv") or {}).items() if not k.startswith("_")}
    if ltv:
        lines += [
            "\n## The local LTV regression under each sampling distribution\n",
            "| distribution | [A B] error (median over t) | condition, unit diagonal | projection spread |",
            "|---|---|---|---|",
        ]
        lines += [
            f"| {k} | {v['model_error']:.3g} | {v['condition_unit_diagonal']:.3g} | "
            f"{v['projection_spread']:.3g} |"
            for k, v in ltv.items()
        ]
    return "\n".join(lines) + "\n"


def _g(x) -> str:
    """A number, or an interval [lo, hi], at three significant digits."""
    return f"[{x[0]:.3g}, {x[1]:.3g}]" if isinstance(x, list) else f"{x:.3g}"
