"""The control study (experiments/control_study.py) with several seeds and random starts."""

import dataclasses
import json
import os

import jax.numpy as jnp
import numpy as np
import pytest


@pytest.mark.slow
def test_random_starts_are_each_judged_against_the_oracle_from_the_same_start(tmp_path):
    """``experiment.control.starts`` 2 on the smoke preset, 3 iterations: every start's
    oracle cost is the single oracle solve from that start's stored controls, D2C close to
    it from each, the table lists them (the seeds: tests/test_reproduce.py)."""
    from configs.smoke_control import CONFIG
    from experiments.run import run
    from mjx_surrogate.control import chunked
    from mjx_surrogate.runs.resolution import resolve, solver_params

    cfg = dataclasses.replace(
        CONFIG,
        solver=dataclasses.replace(CONFIG.solver, max_iter=3),  # unfinished: each start its own cost
        surrogate=dataclasses.replace(CONFIG.surrogate, kinds=("sindy",)),  # seeds: the quick reproduction
        experiment=dataclasses.replace(CONFIG.experiment, out_dir=str(tmp_path)),
        extensions={**CONFIG.extensions, "experiment.control": {"starts": 2}},
    )
    folder = run(cfg, name="starts")
    m = json.load(open(os.path.join(folder, "metrics.json")))
    arrays = np.load(os.path.join(folder, "arrays.npz"))
    starts = m["starts"]
    assert starts["n"] == 2 and [r["start"] for r in starts["rows"]] == [0, 1]
    U0s = arrays["starts_U0"]
    assert U0s.shape[0] == 2 and not np.allclose(U0s[0], U0s[1])  # distinct random starts
    res = resolve(cfg)
    params, _ = solver_params(res.config)
    for i, row in enumerate(starts["rows"]):
        alone = chunked.solve_exact(
            res.system, res.task, jnp.asarray(U0s[i]), params, jacobians=cfg.experiment.oracle
        )
        assert row["oracle_cost"] == pytest.approx(float(alone.out.cost), rel=1e-9)
        assert row["d2c_status"] == row["oracle_status"] == "max_iter" and abs(row["relative_gap"]) < 1e-2, (
            row
        )
    assert starts["rows"][0]["oracle_cost"] != pytest.approx(starts["rows"][1]["oracle_cost"], rel=1e-8)
    assert [r["model"] for r in m["surrogate_rows"]] == ["SINDy cubic_trig"]
    assert "From 2 random starts" in open(os.path.join(folder, "control_table.md")).read()
    assert list(m["stages"]) == ["d2c", "exact", "starts", "surrogates/0.1"]


@pytest.mark.parametrize("starts", ["1", "-2"])
def test_a_bad_number_of_starts_exits_2_naming_the_field_before_any_run(tmp_path, capsys, starts):
    from experiments import run as cli

    assert cli.main(["smoke_control", "--out", str(tmp_path), "--experiment.control.starts", starts]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: experiment.control.starts: must be 0 (off) or at least 2, got {starts}"), (
        err
    )
    assert len(err.strip().splitlines()) == 1 and not os.listdir(tmp_path)
