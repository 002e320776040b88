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


def test_the_counts_of_a_few_trials_beside_many_labels_are_drawn() -> None:
    """890 trials in a bin beside 21,000 held-out labels: on a linear axis their bar was a line of no height."""
    import matplotlib.pyplot as plt

    rng = np.random.default_rng(1)
    many, few = rng.random(21000), rng.random(30)
    fig = plot.figure([("labels", reliability((rng.random(21000) < many).astype(float), many)),
                       ("trials", reliability(np.ones(30), few))], "p_hold")
    fig.tight_layout()
    fig.canvas.draw()
    counts = fig.axes[1]
    bars = [b for b in counts.patches if b.get_height() > 0]
    smallest = min(bars, key=lambda b: b.get_height()).get_window_extent()
    assert smallest.height > 0.05 * counts.get_window_extent().height
    plt.close(fig)


def test_a_bin_of_one_grasp_is_drawn_beside_a_bin_of_two_and_no_count_draws_no_warning() -> None:
    """On the log axis the counts' lower limit came from the smallest count: a bin of one grasp beside one of two
    was a sliver along the bottom edge; with every bin empty matplotlib warned that nothing could be log-scaled."""
    import warnings

    import matplotlib.pyplot as plt

    fig = plot.figure([("trials", reliability(np.ones(3), np.array([0.95, 0.5, 0.52])))], "p_hold")
    fig.tight_layout()
    fig.canvas.draw()
    counts = fig.axes[1]
    frame = counts.get_window_extent()
    one = next(b for b in counts.patches if b.get_height() == 1).get_window_extent()
    assert min(one.y1, frame.y1) - max(one.y0, frame.y0) > 0.25 * frame.height
    plt.close(fig)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert plot.reliability_png([("none", reliability(np.zeros(0), np.zeros(0)))], "p_hold").startswith(b"\x89PNG")


def test_a_bin_predicted_at_one_is_drawn_whole() -> None:
    """The quick start's report drew the mug's 3 trials (p_hold >0.999) on the frame's right edge, the marker cut in
    half; the counts' bars share the axis."""
    import matplotlib.pyplot as plt

    fig = plot.figure([("trials: MuJoCo 3", reliability(np.ones(3), np.full(3, 0.9999)))], "p_hold")
    ax, counts = fig.axes
    assert ax.get_xlim()[0] < 0.0 and ax.get_xlim()[1] > 1.0 and counts.get_xlim() == ax.get_xlim()
    plt.close(fig)
