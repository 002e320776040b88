"""The reliability diagram's picture: every curve visible, every legend line whole."""

from __future__ import annotations

import numpy as np

from planner.calibration import plot
from planner.calibration.metrics import reliability


def test_no_legend_lies_over_a_curve_and_a_bin_that_all_held_is_drawn_whole() -> None:
    """`grasp report` drew the legend ("best") over a curve of trials that all held, which ran along the frame's
    top edge, its markers cut in half; the trials' long legend line ran off the figure."""
    import matplotlib.pyplot as plt

    rng = np.random.default_rng(0)
    p = rng.random(500)
    held_out = reliability((rng.random(500) < p).astype(float), p)
    trials = reliability(np.ones(300), rng.random(300))  # every grasp tried held
    label = "trials: MuJoCo 1035, PyBullet 0 (MuJoCo's verdict where both tried a grasp)"
    fig = plot.figure([("held out on its labels: the model's source", held_out), (label, trials)], "p_hold")
    fig.tight_layout()
    fig.canvas.draw()
    ax = fig.axes[0]
    legend = ax.get_legend()
    assert not legend.get_window_extent().overlaps(ax.get_window_extent())
    assert all(t.get_window_extent().x1 <= fig.bbox.x1 for t in legend.get_texts())
    low, high = ax.get_ylim()
    assert low < 0.0 and high > 1.0
    plt.close(fig)
    assert plot.reliability_png([("held out", held_out)], "p_hold").startswith(b"\x89PNG")
