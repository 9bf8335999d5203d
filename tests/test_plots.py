"""runs.plots: cost figures on a log scale where the costs allow it."""

import warnings

import matplotlib.pyplot as plt
import numpy as np

from mjx_surrogate.runs import plots


def test_cost_figures_are_log_scaled_unless_a_cost_is_zero():
    """A hold task started at an equilibrium costs 0 from the first iteration: its figures
    use a linear axis, without matplotlib's warning; positive costs keep the log axis."""
    positive, zero = np.array([4.0, 1.0, 0.5]), np.array([0.0, 0.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for histories, scale in (({"d2c": positive}, "log"), ({"d2c": positive, "hold": zero}, "linear")):
            fig = plots.cost_history(histories)
            assert fig.axes[0].get_yscale() == scale
            plt.close(fig)
            curves = {k: (np.arange(len(v)) * 100, v) for k, v in histories.items()}
            fig = plots.cost_vs_simulations(curves)
            assert fig.axes[0].get_yscale() == scale
            plt.close(fig)
