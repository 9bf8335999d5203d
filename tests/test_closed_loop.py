"""mjx_surrogate/analysis/closed_loop.py: the closed-loop verdict's rule on hand-made rows, every outcome."""

import pytest

from mjx_surrogate.analysis.closed_loop import MATCH_TOL, cause_text, closed_loop_verdict, table


def _rows(costs: dict, goals: dict | None = None, conditions=(("model", 0.0), ("model", 0.05))) -> list[dict]:
    """Rows of the run's shape: costs[label] one median per condition (None: diverged)."""
    out = []
    for ci, (s, w) in enumerate(conditions):
        for label, cs in costs.items():
            out.append(
                {
                    "controller": label,
                    "plant": s,
                    "process_noise": w,
                    "costs": [cs[ci]],
                    "cost_median": cs[ci],
                    "goal_reached": (goals or {}).get(label, [1.0] * len(conditions))[ci],
                    "black_box_steps_per_control_step": 0.0,
                    "iterations_per_replan": None,
                    "compute_per_step_s": 0.01,
                    "real_time_factor": 10.0,
                }
            )
    return out


def test_held_when_no_surrogate_comes_within_the_tolerance():
    v = closed_loop_verdict(
        _rows({"D2C-MPC": [100, 120], "SINDy poly MPC": [150, 400], "MLP MPC": [900, None]})
    )
    assert v["verdict"] == "held"
    assert v["conditions"][0]["ratios"] == {"SINDy poly MPC": 1.5, "MLP MPC": 9.0}
    assert v["conditions"][1]["ratios"]["MLP MPC"] is None  # diverged: never a match


def test_did_not_hold_when_one_surrogate_matches_everywhere():
    v = closed_loop_verdict(
        _rows({"D2C-MPC": [100, 120], "SINDy cubic_trig MPC": [101, 125], "MLP MPC": [900, 900]})
    )
    assert v["verdict"] == "did not hold" and "SINDy cubic_trig MPC" in v["text"]
    edge = 100 * (1 + MATCH_TOL)
    assert (
        closed_loop_verdict(_rows({"D2C-MPC": [100, 100], "MLP MPC": [edge, edge]}))["verdict"]
        == "did not hold"
    )
    above = closed_loop_verdict(_rows({"D2C-MPC": [100, 100], "MLP MPC": [edge * 1.001, edge * 1.001]}))
    assert above["verdict"] == "held"


def test_in_part_and_goal_counts():
    v = closed_loop_verdict(_rows({"D2C-MPC": [100, 120], "SINDy MPC": [105, 300]}))
    assert v["verdict"] == "held in part" and "noise 0 (SINDy MPC)" in v["text"]
    # as cheap, but at the goal less often than D2C-MPC: not a match
    goals = {"D2C-MPC": [1.0, 1.0], "SINDy MPC": [0.5, 0.5]}
    assert (
        closed_loop_verdict(_rows({"D2C-MPC": [100, 100], "SINDy MPC": [90, 90]}, goals))["verdict"] == "held"
    )


def test_a_condition_where_d2c_mpc_fails_is_not_judged():
    costs = {"D2C-MPC": [100, None, 5e4], "MLP MPC": [500, 600, 1e5]}
    conditions = (("model", 0.0), ("model", 0.05), ("mass=1.5", 0.0))
    v = closed_loop_verdict(_rows(costs, conditions=conditions), offline_cost=1000)
    assert [c["judged"] for c in v["conditions"]] == [True, False, False]  # diverged; over 10x the optimum
    assert v["verdict"] == "held" and "Not judged" in v["text"] and "plant mass=1.5, noise 0" in v["text"]
    assert closed_loop_verdict(_rows(costs, conditions=conditions), offline_cost=1e4)["conditions"][2][
        "judged"
    ]
    none = closed_loop_verdict(_rows({"D2C-MPC": [None, None], "MLP MPC": [1, 1]}))
    assert none["verdict"] == "inconclusive"


def test_not_measured_without_both_sides_and_the_table_leads_with_the_verdict():
    assert (
        closed_loop_verdict(_rows({"D2C-MPC": [1, 1], "TVLQR tracking": [1, 1]}))["verdict"] == "not measured"
    )
    rows = _rows({"D2C-MPC": [100, 120], "MLP MPC": [900, 900]})
    rows[1]["closed_loop_one_step_error"] = 0.125
    v = closed_loop_verdict(rows) | {"cause": cause_text(rows)}
    assert "MLP MPC 12.5 %" in v["cause"] and "plant model" in v["cause"]
    text = table(rows, 0.1, v)
    assert text.startswith("**Closed loop, the paper's claim: held**") and "MLP MPC 12.5 %" in text
    assert text.count("### Plant model, process noise") == 2


def test_the_one_step_error_against_numpy():
    """The cause's measure: a model that knows the loop's steps has error 0; one that holds the
    state has the loop's median step length over the optimum's RMS state."""
    from types import SimpleNamespace

    import jax.numpy as jnp
    import numpy as np

    from experiments.mpc_study import _one_step_error

    rng = np.random.default_rng(0)
    U = rng.normal(size=(20, 1))
    A, B = np.array([[1.0, 0.1], [-0.2, 0.95]]), np.array([[0.0], [0.1]])
    X = [np.array([1.0, -0.5])]
    for u in U:
        X.append(A @ X[-1] + B @ u)
    X = np.array(X)
    optimum = {"X_star": 2 * X}
    exact = SimpleNamespace(step=lambda x, u: jnp.asarray(A) @ x + jnp.asarray(B) @ u)
    hold = SimpleNamespace(step=lambda x, u: x)
    assert _one_step_error(exact, X, U, optimum) < 1e-12
    scale = np.sqrt(np.mean(np.sum((2 * X) ** 2, -1)))
    expected = np.median(np.linalg.norm(np.diff(X, axis=0), axis=-1)) / scale
    assert _one_step_error(hold, X, U, optimum) == pytest.approx(expected, rel=1e-9)


def test_in_goal_from_is_where_the_episode_entered_the_goal_for_good():
    """The first step from which every state passes; None when the last state fails (an
    episode that swung up and fell again never counts as held)."""
    from mjx_surrogate.analysis.closed_loop import _entered, in_goal_from

    assert in_goal_from([False, False, True, True]) == 2
    assert in_goal_from([True, True, True]) == 0
    assert in_goal_from([False, True, False, True, True]) == 3  # left the goal once: the later entry
    assert in_goal_from([False, True, True, False]) is None  # fell again
    assert _entered({"in_goal_from_s": [1.0, 3.0, 2.0]}) == "2 (3)"
    assert _entered({"in_goal_from_s": [1.0, None]}) == "- (1 of 2 stay)"
