"""Extension points, used from outside the package as docs/extending.md shows: a new
identification scheme and a new surrogate kind are one function each plus one registry
entry, and then run end to end from a config."""

import dataclasses
import glob

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import mjx_surrogate as ms
from experiments import run as cli
from mjx_surrogate.identification import sysid
from mjx_surrogate.runs.results import load_run


def coordinate_differences(step, X, U, key, p):
    """Toy scheme: central differences along each coordinate of [x, u] (2 (nx + nu) T
    one-step calls, no randomness), fitted by the shared least squares."""
    T, nu = U.shape
    nx = X.shape[-1]
    E = p.sigma_x * jnp.eye(nx + nu, dtype=X.dtype)  # [n, nx+nu]
    dz = jnp.broadcast_to(E, (T,) + E.shape)
    xs = jnp.concatenate([X[:-1, None] + dz[..., :nx], X[:-1, None] - dz[..., :nx]], axis=1)
    us = jnp.concatenate([U[:, None] + dz[..., nx:], U[:, None] - dz[..., nx:]], axis=1)
    f = jax.vmap(step)(xs.reshape(-1, nx), us.reshape(-1, nu)).reshape(T, 2 * (nx + nu), nx)
    return sysid.lstsq_ltv(dz, 0.5 * (f[:, : nx + nu] - f[:, nx + nu :]), nx)


@jax.tree_util.register_dataclass
@dataclasses.dataclass
class AffineModel:
    """x_{t+1} = [x, u, 1] W, a global affine surrogate."""

    W: jax.Array  # [nx + nu + 1, nx]

    def step(self, x, u):
        return jnp.concatenate([x, u, jnp.ones(x.shape[:-1] + (1,), x.dtype)], -1) @ self.W


def fit_affine(ctx, train, test, key):
    Z = jnp.concatenate([train.x, train.u, jnp.ones((train.x.shape[0], 1), train.x.dtype)], -1)
    W = jnp.linalg.lstsq(Z, train.x_next)[0]
    return {"affine": ms.Fitted(AffineModel(W), {"n_params": int(W.size)})}


@pytest.fixture(autouse=True)
def registered():
    ms.register_scheme(
        "coordinate",
        ms.IdentificationScheme(
            lambda system, p: lambda X, U, K, key: coordinate_differences(system.step, X, U, key, p),
            lambda T, n: 2 * T * 3,
            "central differences along each coordinate",
        ),
    )
    ms.register_surrogate("affine", ms.SurrogateKind(fit_affine, description="x' = [x, u, 1] W"))
    yield
    sysid.SCHEMES.pop("coordinate")
    ms.surrogates.SURROGATES.pop("affine")


@pytest.mark.slow
def test_a_registered_scheme_drives_d2c_to_the_exact_optimum():
    cfg = ms.Config(
        system=ms.SystemConfig(name="pendulum", backend="native"),
        task=ms.TaskConfig(preset="pendulum_d2c", T=20),
        solver=ms.SolverConfig(sysid="coordinate", sigma_x=1e-4, n_samples=3),
    )
    cfg, system, task = ms.resolve(cfg)
    params, sid = ms.solver_params(cfg)
    U0 = jnp.zeros((task.T, 1))
    d2c = ms.solve_d2c(system, task, U0, jax.random.key(0), params, sid)
    # central differences of the black box (checked against jacfwd in tests/test_sysid.py)
    exact = ms.solve_exact(system, task, U0, params, jacobians="finite_difference")
    assert bool(d2c.converged)
    assert float(d2c.cost) == pytest.approx(float(exact.cost), rel=1e-4)


@pytest.mark.slow
def test_a_registered_scheme_and_surrogate_run_from_the_cli(tmp_path):
    code = cli.main(
        [
            "smoke_predict",
            "--out",
            str(tmp_path),
            "--solver.sysid",
            "coordinate",
            "--solver.sigma_x",
            "1e-4",
            "--surrogate.kinds",
            "sindy",
            "affine",
        ]
    )
    (path,) = glob.glob(str(tmp_path / "*smoke_predict"))
    metrics, arrays = load_run(path)
    assert code == 0 and metrics["status"] == "converged"
    for level in ("0.1", "0.6"):
        models = metrics["results"][level]
        assert list(models)[:4] == ["SINDy cubic_trig", "SINDy quartic", "affine", "LTV"]
        assert models["affine"]["n_params"] == 8 and models["affine"]["one_step_rmse"] > 0
        assert np.isfinite(arrays[f"level{0 if level == '0.1' else 1}_pred_affine"]).all()


def test_unregistered_names_are_rejected_before_any_compile(tmp_path, capsys):
    assert cli.main(["smoke_predict", "--out", str(tmp_path), "--surrogate.kinds", "gp"]) == 2
    assert capsys.readouterr().err.startswith("error: surrogate.kinds[0]: unknown surrogate kind 'gp'")


def test_a_scheme_without_a_t_test_refuses_a_significance(tmp_path, capsys):
    """``sysid_significance`` > 0 needs a scheme that applies it (``t_test``)."""
    argv = ["smoke_d2c", "--out", str(tmp_path), "--solver.sysid", "coordinate"]
    assert cli.main(argv + ["--solver.sysid_significance", "3"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: solver.sysid_significance: needs a scheme with a t-test (central_diff")
