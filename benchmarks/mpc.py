"""Receding-horizon control on the black box: cost, black-box calls and compute per control step.

Per system (``--backend``, native MuJoCo by default; the preset's task with the horizon cut
to ``--horizon`` steps) and per controller, one episode of ``--steps`` control steps from
the task's start, or ``--episodes`` run together by ``vmap`` from starts around it:

* "d2c", and the "finite_difference" and "jacfwd" oracles: at most ``--iterations`` iLQR
  iterations per replan (D2C-MPC's identification as ``mpc_params``: nx + nu orthogonal
  samples); "d2c_reuse": D2C-MPC with its models carried across replans
  (``mjx_surrogate.control.mpc_reuse``, ``--reuse-tol``, ``--reuse-max``);
* the derivative-free "predictive_sampling", "mppi" and "cem": ``--samples`` samples per
  replan of spread ``SAMPLING_SIGMA`` (control units), every step its own value or plans
  held at ``--knots`` knots (a linear spline); MPPI's temperature is 1 % of the start's
  zero-control plan cost, CEM's spread floor a tenth of its start.

Each on plants whose pole masses are ``--mass-scales`` times the model's (1: the model
itself; others through ``mujoco.MjSpec``), for ``--tasks``: the preset's terminal-only
task ("terminal") and one with a running state cost Q = ``--running-weight`` Q_f
("running"). Reported (medians over the episodes): closed-loop cost, the goal cost at the
end, black-box control steps simulated per control step (D2C and the sampling MPCs; the
oracles' Jacobians are not counted), compute time per control step (the second call of
the compiled episodes, compile apart), the real-time factor (control period / compute per
step) and episode control steps per second (all episodes together).

    python benchmarks/mpc.py [--systems pendulum cartpole] [--controllers d2c mppi] [--json out.json]
    python benchmarks/mpc.py --backend mjx --tasks running --mass-scales 1 --samples 4096  # a GPU
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

HEAVY_BODY = {"pendulum": "pole", "cartpole": "pole"}
SAMPLING_SIGMA = {"pendulum": 1.0, "cartpole": 5.0}  # the samples' spread, control units
CONTROLLERS = ("d2c", "d2c_reuse", "finite_difference", "jacfwd", "predictive_sampling", "mppi", "cem")
TASKS = ("terminal", "running")


def _heavier(system_name: str, scale: float, folder: str, backend: str):
    """The preset's model with its pole's geom masses scaled (MjSpec), on ``backend``."""
    import mujoco

    from mjx_surrogate.systems import from_mjcf, make_system

    base = make_system(system_name, backend)
    spec = mujoco.MjSpec.from_string(base.xml)
    for geom in spec.body(HEAVY_BODY[system_name]).geoms:
        geom.mass *= scale
    path = os.path.join(folder, f"{system_name}_heavier.xml")
    with open(path, "w") as f:
        f.write(spec.to_xml())
    return from_mjcf(path, backend=backend, substeps=base.substeps)


def run(
    system_name: str,
    horizon: int,
    steps: int,
    iterations: int,
    mass_scales: list[float],
    running_weight: float,
    controllers: list[str],
    samples: int,
    knots: int = 0,
    backend: str = "native",
    task_names: tuple[str, ...] = TASKS,
    episodes: int = 1,
    reuse: tuple[float, int] = (0.1, 4),
) -> list[dict]:
    import jax
    import jax.numpy as jnp
    import numpy as np

    from mjx_surrogate.control import mpc, mpc_reuse, mpc_sampling
    from mjx_surrogate.runs.config import Config, SystemConfig, TaskConfig
    from mjx_surrogate.runs.resolution import mpc_params, resolve
    from mjx_surrogate.tasks import goal_cost, trajectory_cost
    from mjx_surrogate.trajectory import open_loop

    task_config = TaskConfig(preset=f"{system_name}_d2c", T=horizon)  # the paper's task of the system
    res = resolve(Config(SystemConfig(system_name, backend=backend), task_config))
    system, task = res.system, res.task
    params, sid = mpc_params(res.config)
    params = params.replace(max_iter=iterations)
    U0 = jnp.zeros((horizon, system.nu))
    dt = float(system.dt)
    sigma = SAMPLING_SIGMA[system_name]
    folder = tempfile.mkdtemp(prefix="mpc_plant_")
    plants = {}
    for s in mass_scales:
        plants["same plant" if s == 1 else f"pole mass x{s:g}"] = (
            None if s == 1 else _heavier(system_name, s, folder, backend)
        )
    # the preset's task is terminal-only (the paper's); a receding horizon then always
    # plans to arrive at its end, so a running state cost is the second variant
    variants = {
        "terminal": ("terminal only", task),
        "running": (f"Q = {running_weight:g} Q_f", task.replace(Q=running_weight * task.Q_f)),
    }
    tasks = dict(variants[n] for n in task_names)
    noise = 0.01 * jax.random.normal(jax.random.key(1), (episodes, system.nx), task.x0.dtype)
    starts = task.x0 + noise
    rows = []
    for (task_name, task), (plant_name, plant) in itertools.product(tasks.items(), plants.items()):
        # MPPI's temperature: a fixed fraction of the start's zero-control plan cost
        temperature = 0.01 * float(trajectory_cost(task, *open_loop(system.step, task.x0, U0)))
        for controller in controllers:
            spline = "linear" if knots else "zero"
            sampling = mpc_sampling.SamplingSettings(controller, samples, knots, spline)
            if controller in ("predictive_sampling", "mppi", "cem"):
                spread = mpc_sampling.hyper(sigma, temperature, 0.1 * sigma, task.x0.dtype)

                def one(x0, task=task, plant=plant, sampling=sampling, spread=spread):
                    start = task.replace(x0=x0)
                    return mpc_sampling.sampling_mpc(
                        system,
                        start,
                        U0,
                        key=jax.random.key(0),
                        steps=steps,
                        settings=sampling,
                        hyper=spread,
                        plant=plant,
                    )
            else:
                if controller == "d2c_reuse":
                    fn, extra = (
                        mpc_reuse.carried_receding_horizon,
                        {"settings": mpc_reuse.D2CPlannerSettings(*reuse)},
                    )
                else:
                    fn, extra = mpc.receding_horizon, {"controller": controller}

                def one(x0, task=task, plant=plant, fn=fn, extra=extra):
                    return fn(
                        system,
                        task.replace(x0=x0),
                        U0,
                        key=jax.random.key(0),
                        steps=steps,
                        params=params,
                        sysid=sid,
                        plant=plant,
                        **extra,
                    )

            # one episode from the task's start, or a batch of episodes (vmap) from starts around it
            episode = (lambda: one(task.x0)) if episodes == 1 else (lambda: jax.vmap(one)(starts))  # noqa: E731
            call = lambda: jax.block_until_ready(episode())  # noqa: E731
            t0 = time.perf_counter()
            call()
            first = time.perf_counter() - t0
            t0 = time.perf_counter()
            r = call()
            run_s = time.perf_counter() - t0
            per_step = run_s / steps
            if controller in ("d2c", "d2c_reuse"):
                flat = r._replace(identified=r.identified.reshape(-1, r.identified.shape[-1]))
                calls = mpc.black_box_steps(
                    flat._replace(iterations=r.iterations.reshape(-1)), horizon, params.n_alphas, sid
                )
            elif controller in ("predictive_sampling", "mppi", "cem"):
                calls = np.array([mpc_sampling.black_box_steps(sampling, horizon)])
            else:
                calls = None
            X_end = r.X[..., -1, :].reshape(-1, system.nx)
            rows.append(
                {
                    "system": system_name,
                    "backend": backend,
                    "device": jax.devices()[0].platform,
                    "samples": samples if controller in ("predictive_sampling", "mppi", "cem") else None,
                    "task": task_name,
                    "plant": plant_name,
                    "controller": controller,
                    "episodes": episodes,
                    "cost": float(np.median(r.cost)),
                    "episode_costs": [float(c) for c in np.ravel(r.cost)],
                    "final_goal_cost": float(np.median(jax.vmap(goal_cost, (None, 0))(task, X_end))),
                    "iterations_per_replan": float(np.mean(np.asarray(r.iterations))),
                    "black_box_steps_per_control_step": None if calls is None else float(calls.mean()),
                    "compile_s": first - run_s,
                    "compute_per_step_s": per_step,
                    "real_time_factor": dt / per_step,
                    "episode_steps_per_s": episodes * steps / run_s,
                }
            )
            row = rows[-1]
            print(
                f"{system_name:9s} {task_name:15s} {plant_name:18s} {controller:17s} cost {row['cost']:.6g}  "
                f"goal {row['final_goal_cost']:.2e}  it/replan {row['iterations_per_replan']:.2f}  "
                f"bb/step {row['black_box_steps_per_control_step'] or '-'}  "
                f"{1e3 * per_step:.1f} ms/step (x{row['real_time_factor']:.1f} real time)  "
                f"compile {row['compile_s']:.1f} s",
                flush=True,
            )
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--systems", nargs="+", default=["pendulum", "cartpole"])
    ap.add_argument("--horizon", type=int, default=40)
    ap.add_argument("--steps", type=int, default=80)
    ap.add_argument("--iterations", type=int, default=5)
    ap.add_argument("--backend", default="native", choices=["native", "mjx"])
    ap.add_argument("--mass-scales", nargs="+", type=float, default=[1.0, 1.5], help="plants (1: the model)")
    ap.add_argument("--tasks", nargs="+", default=list(TASKS), choices=TASKS)
    ap.add_argument("--running-weight", type=float, default=0.01, help="the second task's Q / Q_f")
    ap.add_argument("--controllers", nargs="+", default=list(CONTROLLERS), choices=CONTROLLERS)
    ap.add_argument("--samples", type=int, default=256, help="samples per replan of the sampling MPCs")
    ap.add_argument("--knots", type=int, default=0, help="the sampling MPCs' knots (0: every step)")
    ap.add_argument("--episodes", type=int, default=1, help="episodes run together (vmap), starts around x0")
    ap.add_argument("--reuse-tol", type=float, default=0.1, help="d2c_reuse: the carried models' test")
    ap.add_argument("--reuse-max", type=int, default=4, help="d2c_reuse: replans in a row on them")
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    from mjx_surrogate.control.mpc_reuse import D2CPlannerSettings
    from mjx_surrogate.errors import ConfigError

    try:
        D2CPlannerSettings(a.reuse_tol, a.reuse_max).check()
    except ConfigError as e:
        ap.error(f"--{e.field.replace('_', '-')}: {str(e).removeprefix(e.field + ': ')}")

    from mjx_surrogate.runtime import configure_runtime

    configure_runtime(x64=True)
    rows = []
    for name in a.systems:
        rows += run(
            name,
            a.horizon,
            a.steps,
            a.iterations,
            a.mass_scales,
            a.running_weight,
            a.controllers,
            a.samples,
            a.knots,
            a.backend,
            tuple(a.tasks),
            a.episodes,
            (a.reuse_tol, a.reuse_max),
        )
    if a.json:
        with open(a.json, "w") as f:
            json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
