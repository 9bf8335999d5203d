"""Models of black boxes with many states from data: SINDy on POD coefficients
(:mod:`mjx_surrogate.surrogates.pod_sindy`) and the local LTV model in the data's own
snapshot basis (:func:`mjx_surrogate.identification.sysid_reduced.fit_in_snapshot_basis`), on a linear
system whose states stay in a 3-dimensional subspace of R^12: both exact at the subspace's
rank, the POD model with an error floor below it."""

import jax.numpy as jnp
import numpy as np
import pytest

from experiments import run as cli
from mjx_surrogate.identification import step_models, sysid
from mjx_surrogate.identification.data import Dataset
from mjx_surrogate.surrogates import library, pod_sindy

rng = np.random.default_rng(11)
NX, R, NU, T = 12, 3, 1, 15
PHI = np.linalg.qr(rng.normal(size=(NX, R)))[0]  # the subspace
A_R = 0.9 * np.linalg.qr(rng.normal(size=(R, R)))[0]
B_R = rng.normal(size=(R, NU))


def trajectories(n):
    """n trajectories from starts in the subspace: x_{t+1} = Phi (A_r Phi' x + B_r u)."""
    X = np.zeros((n, T + 1, NX))
    X[:, 0] = rng.normal(size=(n, R)) @ PHI.T
    U = rng.normal(size=(n, T, NU))
    for t in range(T):
        X[:, t + 1] = (X[:, t] @ PHI @ A_R.T + U[:, t] @ B_R.T) @ PHI.T
    return X, U


def test_pod_sindy_is_exact_at_the_subspaces_rank_and_has_a_floor_below():
    X, U = trajectories(40)
    x, u, xn = (a.reshape(-1, a.shape[-1]) for a in (X[:, :-1], U, X[:, 1:]))
    spec = library.parse("poly1", (), 1)
    Xt, Ut = trajectories(5)
    xt, ut, xnt = (a.reshape(-1, a.shape[-1]) for a in (Xt[:, :-1], Ut, Xt[:, 1:]))
    errors = {}
    for rank in (R, R - 1):
        model, captured = pod_sindy.fit(spec, *(jnp.asarray(a) for a in (x, u, xn)), rank)
        errors[rank] = float(jnp.max(jnp.abs(model.step(jnp.asarray(xt), jnp.asarray(ut)) - xnt)))
        assert (captured > 1 - 1e-12) == (rank == R)
    assert errors[R] < 1e-10 and errors[R - 1] > 1e-2, errors


@pytest.mark.slow
def test_ltv_in_the_snapshot_basis_is_exact_where_the_full_regression_is_not_determined():
    """Deviations from a nominal span 3 of 12 directions: the full-order regression of
    A_t is rank-deficient; in the snapshot basis the lifted model predicts exactly."""
    Xn, Un = (a[0] for a in trajectories(1))
    X, U = trajectories(30)
    X = X - X[:, :1] + Xn[0]  # every trajectory from the nominal's start
    for t in range(T):
        X[:, t + 1] = (X[:, t] @ PHI @ A_R.T + U[:, t] @ B_R.T) @ PHI.T
    dX = jnp.asarray(X - Xn)
    G, _ = sysid._trajectory_statistics(dX, jnp.asarray(U - Un), None)
    assert np.linalg.matrix_rank(np.asarray(G[5]), tol=1e-8) <= R + NU < NX + NU
    model = step_models.fit_reduced_ltv(
        Dataset(jnp.asarray(X), jnp.asarray(U)), jnp.asarray(Xn), jnp.asarray(Un), 1e-12
    )
    Xt, Ut = trajectories(3)
    Xt = Xt - Xt[:, :1] + Xn[0]
    for t in range(T):
        Xt[:, t + 1] = (Xt[:, t] @ PHI @ A_R.T + Ut[:, t] @ B_R.T) @ PHI.T
    pred = step_models.predict(model.step_t, jnp.asarray(Xt[:, 0]), jnp.asarray(Ut))
    assert float(jnp.max(jnp.abs(pred - Xt))) < 1e-9


@pytest.mark.parametrize(
    "argv,needle",
    [
        (["--surrogate.pod_sindy.rank", "0"], "surrogate.pod_sindy.rank: must be between 1 and nx = 32"),
        (["--surrogate.pod_sindy.libraries", "poly2_trig"], "surrogate.pod_sindy.libraries[0]"),
        (["--surrogate.reduced_ltv_tol", "2"], "surrogate.reduced_ltv_tol: must be in [0, 1)"),
    ],
)
def test_bad_pod_settings_are_one_line_before_any_compile(argv, needle, tmp_path, capsys):
    base = ["burgers_predict", "--system.name", "burgers32", "--out", str(tmp_path)]
    assert cli.main(base + argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith(f"error: {needle}"), err
