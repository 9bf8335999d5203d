"""Batch axes over devices and processes give the one-device results.

A device count is fixed when JAX starts, so the multi-device cases run in two processes
on localhost (tests/sharding_check.py), joined by ``jax.distributed``, each with 2 host
CPU devices: meshes of 2 host devices (one process's own) and of 4 devices (both
processes'). On them a D2C solve, a multi-start solve, a data set and a seed-vmapped MLP
fit are compared with the same computation on one device on the native backend, on both
meshes; on the MJX backend, on the 2-device mesh, the sharded parts of a solve (one
identification, one line search's trials) and a data set. The same processes
then run a D2C experiment through the CLI over the 4-device mesh and a one-experiment
sweep.

Tolerances: data sets come out equal to round-off and each MLP's test loss bitwise equal
(every trajectory and network is computed whole on one device; at the suite's LLVM level 0
the sharded and the one-device program of a native data set differ by an ulp, 1.1e-16
seen); a D2C solve sums the regression's
statistics in another order (psum of per-device sums), a round-off difference that 15
iterations carry to ~1e-8 in U and ~1e-11 in cost (float64); MLP weights differ by
float32 round-off (2e-10) in one seed.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import socket
import subprocess
import sys
import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mjx_surrogate import sharding
from mjx_surrogate.errors import ConfigError
from mjx_surrogate.identification import sysid

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
TOL = {
    "d2c_cost": 1e-9,
    "d2c_X": 1e-6,
    "d2c_U": 1e-6,
    "d2c_iterations": 0,
    "multistart_costs": 1e-9,
    "dataset_X": 1e-12,  # round-off; a trajectory drawn from another key differs by O(1)
    "ltv": 1e-8,  # A, B of one identification, and the trial rollouts
}


def _env() -> dict:
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    # the child configures its own runtime; it keeps the suite's code generation level
    level = re.findall(r"--xla_backend_optimization_level=\S+", env.pop("XLA_FLAGS", ""))
    if level:
        env["XLA_FLAGS"] = level[0]
    return env


def _result(path, stdout: str) -> dict:
    assert os.path.exists(path), stdout[-3000:]
    return json.load(open(path))


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("localhost", 0))
        return s.getsockname()[1]


def _check_workload(r: dict, keys: list[str]) -> None:
    assert np.isfinite(r["reference_cost"]) and r["reference_iterations"] > 0, r
    assert sorted(k for k in r if not k.startswith("reference") and k != "mesh_devices") == sorted(keys), r
    for key in keys:
        assert r[key] <= TOL[key], (key, r[key])


def _check_mlp(r: dict) -> None:
    assert r["test_loss"] == 0.0 and r["params"] <= 1e-6, r  # weights: float32 round-off


# Gloo's TCP transport can give up connecting two processes on a loaded host ("Connect
# timeout", once in CI with both test workers busy; not reproduced by a 45 s skew between
# the processes, which the rendezvous absorbs). Such a try is repeated once, with a warning.
GLOO_CONNECT_FAILURE = "Gloo context initialization failed"


def _two_processes(tmp_path, runs, sweep) -> list[tuple[subprocess.Popen, tuple[str, str]]]:
    port = _free_port()
    script = os.path.join(HERE, "sharding_check.py")
    procs = [
        subprocess.Popen(
            [sys.executable, script, "--process-id", str(i), "--port", str(port)]
            + ["--run-dir", str(runs), "--sweep-dir", str(sweep)]
            + ["--result-file", str(tmp_path / f"result-{i}.json")],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=_env(),
            cwd=ROOT,
        )
        for i in range(2)
    ]
    try:
        outs = [p.communicate(timeout=400) for p in procs]
    finally:
        for p in procs:  # bounded in time and cleaned up, whatever happened
            if p.poll() is None:
                p.kill()
                p.wait()
    return list(zip(procs, outs))


@pytest.mark.slow
def test_two_processes_with_two_devices_each_give_the_one_device_results(tmp_path):
    runs, sweep = tmp_path / "runs", tmp_path / "sweep"
    done = _two_processes(tmp_path, runs, sweep)
    if any(p.returncode != 0 and GLOO_CONNECT_FAILURE in err for p, (_, err) in done):
        warnings.warn("Gloo could not connect the two processes; trying once more", stacklevel=1)
        for path in (runs, sweep):
            shutil.rmtree(path, ignore_errors=True)
        done = _two_processes(tmp_path, runs, sweep)
    procs, outs = zip(*done)
    for p, (_, err) in zip(procs, outs):
        assert p.returncode == 0, err[-3000:]
    p0, p1 = (_result(tmp_path / f"result-{i}.json", o) for i, (o, _) in enumerate(outs))
    for i, p in enumerate((p0, p1)):
        assert (p["process"], p["processes"], p["devices"], p["local_devices"]) == (i, 2, 4, 2)
    everything = ["d2c_cost", "d2c_X", "d2c_U", "d2c_iterations", "multistart_costs", "dataset_X"]
    mjx = p0["results"]["mjx/local"]
    assert sorted(mjx) == ["dataset_X", "ltv_A", "ltv_B", "trials_U", "trials_X"], mjx
    assert max(mjx.values()) <= TOL["ltv"] and mjx["dataset_X"] == 0.0, mjx
    _check_mlp(p1["results"]["mlp/local"])
    # A SINDy fit on rows spread over 2 devices is solved on one (docs/performance.md), to round-off.
    sindy_fit = p1["results"]["sindy/local"]
    assert sindy_fit["coef_devices"] == 1 and sindy_fit["coef"] <= 1e-12, sindy_fit
    assert sindy_fit["projections"] <= 1e-12, sindy_fit  # the analysis study's, rows spread
    for p in (p0, p1):
        _check_workload(p["results"]["native/global"], everything)
        assert p["results"]["native/global"]["mesh_devices"] == 2  # one per process

    # The CLI over the 4-device mesh: one run folder, written by process 0 only.
    folders = [f for f in os.listdir(runs) if not f.startswith(".")]
    assert len(folders) == 1, folders
    metrics = json.load(open(runs / folders[0] / "metrics.json"))
    assert metrics["status"] in ("converged", "stalled", "max_iter"), metrics["status"]
    versions = json.load(open(runs / folders[0] / "versions.json"))
    assert versions["parallel"]["processes"] == 2 and versions["parallel"]["mesh_devices"] == 2  # native
    assert p0["run_cost"] == metrics["d2c"]["cost"]

    # The sweep: experiment i on process i mod 2 (one experiment: process 1 has none and
    # waits at the barrier); process 0 writes the one report after both finished.
    assert p0["sweep_status"] == 0 and p1["sweep_status"] == 0
    assert not (sweep / "wall_times-p1.json").exists()  # process 1 ran nothing
    done = sorted(f.split("_", 1)[1] for f in os.listdir(sweep) if (sweep / f / "metrics.json").exists())
    assert done == ["theory"], done
    assert "### The Legendre basis's variance formula" in (sweep / "report.md").read_text()
    assert sorted(json.load(open(sweep / "wall_times-p0.json"))) == ["theory"]


def test_one_device_means_no_mesh_and_too_many_devices_is_a_config_error():
    assert sharding.device_mesh(1) is None
    assert sharding.size(None) == 1
    with pytest.raises(ConfigError, match="parallel.devices"):
        sharding.device_mesh(len(jax.devices()) + 1)


def test_statistics_ignore_zero_weight_padding_and_match_float64_lstsq():
    rng = np.random.default_rng(0)
    T, n, nx, nu = 3, 12, 3, 2
    Z = rng.normal(size=(T, n, nx + nu)) * np.array([1e-3, 1.0, 10.0, 1e-2, 1.0])
    W = rng.normal(size=(T, nx + nu, nx))
    Y = np.einsum("tni,tij->tnj", Z, W)
    w = np.ones(n)
    w[-2:] = 0.0  # padding rows, even non-finite ones, contribute nothing
    Zp, Yp = Z.copy(), Y.copy()
    Zp[:, -2:] = np.nan
    Yp[:, -2:] = np.inf
    G, F = sysid.normal_equations(jnp.asarray(Zp), jnp.asarray(Yp), jnp.asarray(w))
    A, B = sysid.solve_normal_equations(G, F, nx)
    for t in range(T):
        ref = np.linalg.lstsq(Z[t, :-2], Y[t, :-2], rcond=None)[0].T
        np.testing.assert_allclose(np.asarray(A[t]), ref[:, :nx], rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(np.asarray(B[t]), ref[:, nx:], rtol=1e-9, atol=1e-9)
    # Summed in two parts (what two devices do) the statistics are the same.
    G1, F1 = sysid.normal_equations(jnp.asarray(Z[:, :5]), jnp.asarray(Y[:, :5]), jnp.ones(5))
    G2, F2 = sysid.normal_equations(jnp.asarray(Z[:, 5:-2]), jnp.asarray(Y[:, 5:-2]), jnp.ones(5))
    np.testing.assert_allclose(np.asarray(G1 + G2), np.asarray(G), rtol=1e-12)
    np.testing.assert_allclose(np.asarray(F1 + F2), np.asarray(F), rtol=1e-12, atol=1e-15)
