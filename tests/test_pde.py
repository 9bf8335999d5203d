"""PDE black boxes (:mod:`mjx_surrogate.systems.burgers`, :mod:`.allen_cahn`) against
independent NumPy discretisations, and reduced-order identification
(:mod:`mjx_surrogate.identification.sysid_reduced`): exact on a linear PDE, the same optimum as the
full-order scheme on Burgers, and the solver's reduced backward pass against the full one."""

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from experiments import run as cli
from mjx_surrogate.control import d2c
from mjx_surrogate.control.ilqr import ILQRParams, ilqr
from mjx_surrogate.errors import ConfigError
from mjx_surrogate.identification import sysid_reduced
from mjx_surrogate.identification.sysid import SysIdParams, exact_jacobians
from mjx_surrogate.runs import pipeline
from mjx_surrogate.systems import allen_cahn, burgers, registry
from mjx_surrogate.systems.pde import bumps_1d, bumps_2d, laplacian_matrix
from mjx_surrogate.tasks import make_task, task_cost

rng = np.random.default_rng(5)


def burgers_rhs(n, b):
    """The semi-discrete Burgers equation (method of lines), dense NumPy."""
    L = laplacian_matrix(n)

    def rhs(w, u):
        w2 = w * w
        return burgers.VISCOSITY * L @ w - (np.roll(w2, -1) - np.roll(w2, 1)) * n / 4 + b @ u

    return rhs


def imex_numpy(n, nu_visc, rhs_explicit, b, u, w, dt, substeps, L):
    """The IMEX Euler scheme with a dense solve instead of the FFT."""
    tau = dt / substeps
    M = np.eye(L.shape[0]) - tau * nu_visc * L
    for _ in range(substeps):
        w = np.linalg.solve(M, w + tau * rhs_explicit(w) + tau * b @ u)
    return w


def test_burgers_step_is_the_imex_scheme_and_converges_to_the_semi_discrete_pde():
    """One control step against (a) the same IMEX scheme with a dense NumPy solve (round-off)
    and (b) SciPy's integrator of the semi-discrete equation: the first-order scheme's
    error is O(tau) and halves when the substeps double."""
    n = 32
    b = bumps_1d(n, burgers.N_ACTUATORS, 1 / 16)
    x = np.sin(2 * np.pi * (np.arange(n) + 0.5) / n) + 0.1 * rng.normal(size=n)
    u = rng.normal(size=burgers.N_ACTUATORS)
    got = np.asarray(jax.jit(burgers.make_system(n).step)(jnp.asarray(x), jnp.asarray(u)))
    conv = lambda w: -(np.roll(w * w, -1) - np.roll(w * w, 1)) * n / 4  # noqa: E731
    L = laplacian_matrix(n)
    dense = imex_numpy(n, burgers.VISCOSITY, conv, b, u, x, burgers.DT, burgers.SUBSTEPS, L)
    np.testing.assert_allclose(got, dense, atol=1e-13)
    rhs = burgers_rhs(n, b)
    exact = solve_ivp(lambda t, w: rhs(w, u), (0, burgers.DT), x, rtol=1e-12, atol=1e-12).y[:, -1]
    finer = imex_numpy(n, burgers.VISCOSITY, conv, b, u, x, burgers.DT, 2 * burgers.SUBSTEPS, L)
    err, err_finer = np.abs(got - exact).max(), np.abs(finer - exact).max()
    assert err < 5e-3 and 0.4 < err_finer / err < 0.6


@pytest.mark.parametrize("dims,n", [(1, 32), (2, 8)])
def test_allen_cahn_step_against_a_dense_numpy_scheme(dims, n):
    s = allen_cahn.make_system(n, dims)
    if dims == 1:
        L, b = laplacian_matrix(n), bumps_1d(n, 8, 1 / 16)
    else:  # the 5-point Laplacian of the row-major n x n grid
        L1 = laplacian_matrix(n)
        L, b = np.kron(L1, np.eye(n)) + np.kron(np.eye(n), L1), bumps_2d(n, 3, 1 / 8)
    x, u = rng.uniform(-1, 1, size=s.nx), rng.normal(size=s.nu)
    got = np.asarray(jax.jit(s.step)(jnp.asarray(x), jnp.asarray(u)))
    want = imex_numpy(
        n, allen_cahn.EPS**2, allen_cahn.reaction, b, u, x, allen_cahn.DT, allen_cahn.SUBSTEPS, L
    )
    np.testing.assert_allclose(got, want, atol=1e-13)


def test_pde_families_are_registered_by_grid_size():
    assert registry.make_function_system("burgers48").nx == 48
    assert registry.make_function_system("allen_cahn2d8").nx == 64
    assert registry.is_function_system("allen_cahn40")
    with pytest.raises(ConfigError, match="system.name.*at least 8 cells"):
        registry.make_function_system("burgers4")


def linear_nominal(n=32, T=12):
    heat = burgers.make_system(n, convective=False)
    U = jnp.asarray(rng.normal(size=(T, heat.nu)))
    X = heat.rollout(jnp.asarray(np.sin(2 * np.pi * np.arange(n) / n))[None], U[None])[0]
    return heat, X, U


def test_reduced_model_of_a_linear_pde_is_the_projected_jacobian():
    """The heat equation: A_t = V_{t+1}' A V_t and B_t = V_{t+1}' B to round-off, the kept
    basis vectors orthonormal, and the rank grows by at most nu per step from 0 at t = 0."""
    heat, X, U = linear_nominal()
    p = SysIdParams(scheme="reduced", n_samples=20)
    A, B, V = jax.jit(
        lambda X, U: sysid_reduced.reduced_central_difference(heat, X, U, jax.random.key(1), p)
    )(X, U)
    Ap, Bp = sysid_reduced.project_model(*exact_jacobians(heat.step, X, U), V)
    np.testing.assert_allclose(A, Ap, atol=1e-10)
    np.testing.assert_allclose(B, Bp, atol=1e-10)
    r = np.asarray(sysid_reduced.basis_rank(V))
    assert r[0] == 0 and np.all(np.diff(r) <= heat.nu) and r.max() > heat.nu
    for t in (1, 5, 12):
        G = np.asarray(V[t].T @ V[t])
        np.testing.assert_allclose(G, np.diag((np.arange(20) < r[t]).astype(float)), atol=1e-12)


def test_the_energy_rule_keeps_fewer_vectors_as_the_tolerance_grows():
    heat, X, U = linear_nominal()
    dX = sysid_reduced.snapshots(heat.rollout, X, U, jax.random.key(2), 20, 1e-3)
    ranks = [
        int(sysid_reduced.basis_rank(sysid_reduced.snapshot_basis(dX, tol))[-1])
        for tol in (1e-12, 1e-6, 1e-2)
    ]
    assert ranks[0] > ranks[1] > ranks[2] >= 1


@pytest.mark.slow
def test_reduced_backward_pass_with_a_full_basis_equals_the_full_one():
    """A reduced model whose basis is the identity must give the full-order iterates: the
    projection of the cost's expansion and the lifting of the gains are exact."""
    heat, X, U = linear_nominal(n=16, T=8)
    fields = burgers.damp_fields(16, T=8)
    task = make_task(**fields)
    lin = lambda X, U, K, key: exact_jacobians(heat.step, X, U)  # noqa: E731
    eye = jnp.broadcast_to(jnp.eye(16), (9, 16, 16))
    lin_r = lambda X, U, K, key: (*exact_jacobians(heat.step, X, U), eye)  # noqa: E731
    args = (heat.step, task_cost(task), task.x0, jnp.zeros((8, heat.nu)), task.u_min, task.u_max)
    p = ILQRParams(max_iter=5)
    full = ilqr(args[0], lin, *args[1:], p, jax.random.key(0))
    from mjx_surrogate.control.ilqr import Problem, ilqr_advance, ilqr_init, ilqr_result

    prob = Problem(heat.step, lin_r, task_cost(task), task.x0, task.u_min, task.u_max, model_rank=16)
    red = ilqr_result(ilqr_advance(prob, ilqr_init(prob, args[3], p, jax.random.key(0)), p))
    np.testing.assert_allclose(red.cost_history, full.cost_history, rtol=1e-12)
    np.testing.assert_allclose(red.K, full.K, atol=1e-9)


@pytest.mark.slow
def test_ro_d2c_reaches_full_d2c_on_burgers_with_fewer_simulations():
    """Burgers on 32 cells: the reduced scheme (16 snapshots) ends within 1e-6 of the
    full-order central scheme's cost, from the same start, both converged, with less than
    half the black-box steps (16 + 2 (16 + 8) = 64 per t against 2 * 80)."""
    s = burgers.make_system(32)
    task = make_task(**burgers.damp_fields(32, T=20), u_min=-5 * np.ones(8), u_max=5 * np.ones(8))
    U0 = jnp.zeros((20, 8))
    full = d2c.solve_d2c(s, task, U0, jax.random.key(0), ILQRParams(), SysIdParams(n_samples=80))
    red = d2c.solve_d2c(
        s, task, U0, jax.random.key(0), ILQRParams(), SysIdParams(scheme="reduced", n_samples=16)
    )
    assert bool(full.converged) and bool(red.converged)
    assert abs(float(red.cost) - float(full.cost)) <= 1e-6 * float(full.cost)
    assert float(red.cost) < 0.9 * float(full.cost_history[0])
    steps = [
        pipeline.simulation_metrics(r, 20, 8, SysIdParams(scheme=sc, n_samples=n))["simulated_steps"]
        for r, sc, n in ((full, "central_difference", 80), (red, "reduced", 16))
    ]
    assert steps[1] < steps[0] / 2


@pytest.mark.parametrize(
    "argv,needle",
    [
        (["--sysid.scheme", "reduced", "--sysid.n_samples", "40"], "sysid.n_samples: the reduced scheme"),
        (["--sysid.rank_tol", "1e-3"], "sysid.rank_tol: only a reduced scheme"),
        (
            ["--sysid.scheme", "reduced", "--sysid.rank_tol", "1.5"],
            "sysid.rank_tol: must be in [0, 1)",
        ),
        (["--system.name", "burgers3"], "system.name: burgers needs at least 8 cells"),
    ],
)
def test_bad_reduced_settings_are_one_line_before_any_compile(argv, needle, tmp_path, capsys):
    base = ["burgers_d2c", "--system.name", "burgers32", "--out", str(tmp_path)]
    assert cli.main(base + argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith(f"error: {needle}"), err


SHARDED = """
import json, sys
import jax
jax.config.update("jax_num_cpu_devices", 2)
from mjx_surrogate.runtime import configure_runtime
configure_runtime(x64=True, compile_cache=False)
import jax.numpy as jnp, numpy as np
from mjx_surrogate import sharding
from mjx_surrogate.control import d2c
from mjx_surrogate.control.ilqr import ILQRParams
from mjx_surrogate.identification.sysid import SysIdParams
from mjx_surrogate.systems import burgers
from mjx_surrogate.systems.function import on_mesh
from mjx_surrogate.tasks import make_task
one = burgers.make_system(32)
two = on_mesh(one, sharding.device_mesh(2))
task = make_task(**burgers.damp_fields(32, T=10))
p = SysIdParams(scheme="reduced", n_samples=15)  # 15 rollouts and 23 one-step samples: padded
U0, params = jnp.zeros((10, 8)), ILQRParams(max_iter=4)
r1, r2 = (d2c.solve_d2c(s, task, U0, jax.random.key(0), params, p) for s in (one, two))
print(json.dumps({"cost": [float(r1.cost), float(r2.cost)], "dX": float(jnp.max(jnp.abs(r1.X - r2.X))),
                  "devices": len(two.mesh.devices.flat)}))
"""


@pytest.mark.slow
def test_ro_d2c_spread_over_two_devices_gives_the_one_device_solve():
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", SHARDED], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    r = json.loads(out.stdout.strip().splitlines()[-1])
    assert r["devices"] == 2 and r["dX"] < 1e-10
    assert r["cost"][1] == pytest.approx(r["cost"][0], rel=1e-12)
