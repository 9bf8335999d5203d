"""Feedback under control noise (mjx_surrogate.analysis.evaluation): the back-off of gains
that do not help, on a scalar integrator whose closed loops are known in closed form."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mjx_surrogate.analysis.evaluation import backed_off_feedback, evaluate_feedback
from mjx_surrogate.systems.function import from_jax
from mjx_surrogate.tasks import make_task

T = 20
SYSTEM = from_jax(lambda x, u: x + u, 1, 1, 0.1, name="integrator", u_min=(-1.0,), u_max=(1.0,))
TASK = make_task([0.0], [0.0], [[1.0]], [[1.0]], [[1.0]], T, (-1.0,), (1.0,))
LEVELS = jnp.asarray([0.0, 0.1])


@pytest.mark.parametrize(
    "gain, scale",
    [
        (-0.6, 1.0),  # x' = 0.4 x + w: the gains help as they are
        (-3.0, 0.5),  # x' = -2 x + w grows; at half, x' = -0.5 x + w helps
        (0.5, 0.0),  # positive feedback is worse than none at every scale
    ],
)
def test_gains_are_kept_backed_off_or_dropped_as_their_closed_loop_says(gain, scale):
    X, U = jnp.zeros((T + 1, 1)), jnp.zeros((T, 1))
    K = jnp.full((T, 1, 1), gain)
    key = jax.random.key(4)
    fb = backed_off_feedback(SYSTEM, TASK, X, U, K, LEVELS, key, 64)
    assert fb.scale == scale
    closed, opened = evaluate_feedback(SYSTEM, TASK, X, U, fb.scale * K, LEVELS, key, 64)
    np.testing.assert_array_equal(fb.closed, closed)  # reported on the evaluation draws
    np.testing.assert_array_equal(fb.opened, opened)
    assert np.median(fb.closed[1]) <= np.median(fb.opened[1])
    if scale == 0.0:
        np.testing.assert_array_equal(fb.closed, fb.opened)
    # given K's own evaluation, the same answer without evaluating it again
    own = evaluate_feedback(SYSTEM, TASK, X, U, K, LEVELS, key, 64)
    again = backed_off_feedback(SYSTEM, TASK, X, U, K, LEVELS, key, 64, own)
    assert again.scale == fb.scale
    np.testing.assert_array_equal(again.closed, fb.closed)


def test_a_backed_off_scale_must_help_on_more_draws_than_chance_explains():
    """The back-off's rule on the draws a scale is chosen on: a median lower by a hair on
    33 of 64 paired draws (sign test p 0.45) is not enough; 45 of 64 (p 0.001) is."""
    from mjx_surrogate.analysis.evaluation import _clearly_helps, _helps

    levels, opened = np.array([0.0, 0.01]), np.ones((2, 64))

    def closed(wins):
        row = np.where(np.arange(64) < wins, 0.99, 1.01)
        return np.stack([np.ones(64), row])

    assert _helps(levels, closed(33), opened) and not _clearly_helps(levels, closed(33), opened)
    assert _clearly_helps(levels, closed(45), opened)
    with_nan = closed(45)
    with_nan[1, :20] = np.nan  # a blown-up closed loop counts against it
    assert not _clearly_helps(levels, with_nan, opened)
    assert _clearly_helps(np.array([0.0]), closed(0), opened)  # only levels > 0 are judged


def test_the_open_loop_replay_applies_the_controls_whatever_the_nominal():
    """A surrogate on which iLQR diverged leaves a nominal X that is not finite: the open
    loop is still U's rollout on the black box (here x_T = sum of U); the closed loop
    around that nominal is not finite."""
    from mjx_surrogate.analysis.evaluation import replay

    U = jnp.full((T, 1), 0.05)
    X = jnp.full((T + 1, 1), jnp.nan)
    out = replay(SYSTEM, TASK, X, U, jnp.full((T, 1, 1), -0.5))
    np.testing.assert_allclose(np.asarray(out.X_open)[:, 0], 0.05 * np.arange(T + 1), atol=1e-12)
    assert np.isfinite(float(out.cost_open)) and not np.isfinite(float(out.cost_closed))
