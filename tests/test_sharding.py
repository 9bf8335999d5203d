"""Batch axes over devices and processes give the one-device results.

A device count is fixed when JAX starts, so the multi-device cases run in subprocesses
(tests/sharding_check.py): 4 host CPU devices (meshes of 2 and 4), and 2 processes on
localhost joined by ``jax.distributed`` (a mesh of 2, one device each). Each compares a
D2C solve, a multi-start solve, a data set and a seed-vmapped MLP fit with the same
computation on one device.

Tolerances: data sets and each MLP's test loss come out bitwise equal (every trajectory
and network is computed whole on one device); a D2C solve sums the regression's
statistics in another order (psum of per-device sums), a round-off difference that 15
iterations carry to ~1e-8 in U and ~1e-11 in cost (float64); MLP weights differ by
float32 round-off (2e-10) in one seed.
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mjx_surrogate import sharding, sysid
from mjx_surrogate.errors import ConfigError

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
TOL = {
    "d2c_cost": 1e-9,
    "d2c_X": 1e-6,
    "d2c_U": 1e-6,
    "d2c_iterations": 0,
    "multistart_costs": 1e-9,
    "dataset_X": 0.0,
}


def _env() -> dict:
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    env.pop("XLA_FLAGS", None)  # the child configures its own runtime
    return env


def _result(stdout: str) -> dict:
    lines = [ln for ln in stdout.splitlines() if ln.startswith("RESULT ")]
    assert lines, stdout[-3000:]
    return json.loads(lines[-1][len("RESULT ") :])


def _check(results: dict, expected: dict) -> None:
    """expected: {backend: {mesh: [quantities]}}; every difference within TOL."""
    for backend, by_mesh in expected.items():
        r = results[backend]
        if backend == "mlp":
            for n in by_mesh:  # each network's test loss bitwise; weights to float32 round-off
                assert r[n]["test_loss"] == 0.0 and r[n]["params"] <= 1e-6, r
            continue
        assert np.isfinite(r["reference_cost"]) and r["reference_iterations"] > 0, r
        for n, keys in by_mesh.items():
            assert sorted(r[n]) == sorted(keys), (backend, n, sorted(r[n]))
            for key in keys:
                assert r[n][key] <= TOL[key], (backend, n, key, r[n][key])


@pytest.mark.slow
def test_meshes_of_2_and_4_host_devices_give_the_one_device_results():
    cmd = [
        sys.executable,
        os.path.join(HERE, "sharding_check.py"),
        "--cpu-devices",
        "4",
        "--meshes",
        "2",
        "4",
        "--mjx-meshes",
        "4",
    ]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=400, env=_env(), cwd=ROOT)
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = _result(proc.stdout)
    assert out["devices"] == 4 and out["processes"] == 1
    everything, solve_and_data = list(TOL), ["d2c_cost", "d2c_X", "d2c_U", "d2c_iterations", "dataset_X"]
    _check(
        out["results"],
        {
            "native": {"2": everything, "4": everything},
            "mjx": {"4": solve_and_data},
            "mlp": {"2": None, "4": None},
        },
    )


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("localhost", 0))
        return s.getsockname()[1]


@pytest.mark.slow
def test_two_processes_joined_by_jax_distributed_give_the_one_device_results(tmp_path):
    port = _free_port()
    procs = [
        subprocess.Popen(
            [
                sys.executable,
                os.path.join(HERE, "sharding_check.py"),
                "--process-id",
                str(i),
                "--num-processes",
                "2",
                "--port",
                str(port),
                "--run-dir",
                str(tmp_path / "runs"),
                "--native",
                "solve",
                "data",
                "--mjx",
                "--no-mlp",
            ],
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
    for p, (_, err) in zip(procs, outs):
        assert p.returncode == 0, err[-3000:]
    out = _result(outs[0][0])
    assert out["devices"] == 2 and out["processes"] == 2
    _check(out["results"], {"native": {"2": ["d2c_cost", "d2c_X", "d2c_U", "d2c_iterations", "dataset_X"]}})
    # One run folder, written by process 0; process 1 wrote nothing there.
    folders = [f for f in os.listdir(tmp_path / "runs") if not f.startswith(".")]
    assert len(folders) == 1, folders
    metrics = json.load(open(tmp_path / "runs" / folders[0] / "metrics.json"))
    assert metrics["status"] in ("converged", "stalled", "max_iter"), metrics["status"]
    versions = json.load(open(tmp_path / "runs" / folders[0] / "versions.json"))
    assert versions["parallel"]["processes"] == 2 and versions["parallel"]["mesh_devices"] == 2
    assert out["run_cost"] == metrics["d2c"]["cost"]


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


@pytest.mark.slow
def test_a_sweep_over_two_processes_runs_each_experiment_once_and_one_report(tmp_path):
    """``experiments.reproduce --distributed``: experiment i runs on process i mod 2, each
    writes its own run folders, process 0 writes the report after both finish."""
    out, report = tmp_path / "runs", tmp_path / "report.md"
    env = dict(_env(), JAX_COORDINATOR_ADDRESS=f"localhost:{_free_port()}", JAX_NUM_PROCESSES="2")
    cmd = [sys.executable, "-m", "experiments.reproduce", "--quick", "--distributed"]
    cmd += ["--out", str(out), "--report", str(report), "--only", "theory", "cartpole_control"]
    procs = [
        subprocess.Popen(
            cmd,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            cwd=ROOT,
            env=dict(env, JAX_PROCESS_ID=str(i)),
        )
        for i in range(2)
    ]
    try:
        outs = [p.communicate(timeout=300) for p in procs]
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
                p.wait()
    for p, (_, err) in zip(procs, outs):
        assert p.returncode == 0, err[-3000:]
    assert "theory: running" in outs[0][0] and "cartpole_control" not in outs[0][0].split("report:")[0]
    assert "cartpole_control: running" in outs[1][0] and "theory" not in outs[1][0]
    folders = sorted(f for f in os.listdir(out) if os.path.isdir(out / f) and not f.startswith("."))
    assert sorted(f.split("_", 1)[1] for f in folders) == ["cartpole_control", "theory"], folders
    text = report.read_text()
    assert "Fig. control" in text and "order N" in text
    assert sorted(json.load(open(out / "wall_times-p0.json"))) == ["theory"]
    assert sorted(json.load(open(out / "wall_times-p1.json"))) == ["cartpole_control"]
