"""The reliability diagram: predicted vs observed success per decile of p_hold (PNG, matplotlib)."""

from __future__ import annotations

import io
import textwrap
from collections.abc import Sequence

import numpy as np

from planner.calibration.metrics import Reliability

#: Room about [0, 1] on both axes: a bin every grasp of which held (or dropped), or predicted at ~1 (or ~0), was drawn
#: on the frame's edge, its marker cut in half.
MARGIN = 0.03


#: [characters] a legend line's longest: the figure is 5 inches wide, and a longer one ran off its edge.
LABEL_WIDTH = 64

#: [grasps] the log count axis's bottom, below one: autoscaled, it sat just under the smallest count, and a bin of
#: one grasp beside a bin of two was a sliver (with no count at all matplotlib warned it could not log-scale).
COUNT_FLOOR = 0.5
#: The count axis's top, this factor above the largest count (room for the bar's top on a log axis).
COUNT_HEADROOM = 2.0


def reliability_png(curves: Sequence[tuple[str, Reliability]], title: str) -> bytes:
    """A PNG of one or more reliability tables (label, table): observed success
    against mean predicted p_hold per bin, the diagonal being perfect
    calibration, and the grasps per bin below."""
    import matplotlib.pyplot as plt

    fig = figure(curves, title)
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100)
    plt.close(fig)
    return buffer.getvalue()


def figure(curves: Sequence[tuple[str, Reliability]], title: str):  # type: ignore[no-untyped-def]
    """The diagram's matplotlib figure (:func:`reliability_png`)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, counts) = plt.subplots(2, 1, figsize=(5, 5.6), gridspec_kw={"height_ratios": [3, 1]}, sharex=True)
    ax.plot([0, 1], [0, 1], color="0.6", linestyle="--", linewidth=1, label="perfect calibration")
    width = 0.1 / max(len(curves), 1)
    for k, (label, r) in enumerate(curves):
        full = r.count > 0
        ax.plot(r.predicted[full], r.observed[full], marker="o",
                label=textwrap.fill(f"{label} (ECE {r.ece:.3f})", LABEL_WIDTH))
        centres = (r.edges[:-1] + r.edges[1:]) / 2
        counts.bar(centres - 0.05 + width * (k + 0.5), r.count, width=width * 0.9, label=label)
    ax.set_xlim(-MARGIN, 1 + MARGIN)  # a bin at p_hold ~1 (the mug's best grasps) sat on the right edge, cut
    ax.set_ylim(-MARGIN, 1 + MARGIN)
    ax.set_ylabel("observed success rate")
    fig.suptitle(title, fontsize=9)
    # above the plot: inside it ("best") it lay over a curve of trials that all held, drawn along the top
    ax.legend(fontsize=7, loc="lower left", bbox_to_anchor=(0.0, 1.01, 1.0, 0.1), mode="expand", borderaxespad=0.0)
    counts.set_xlabel("predicted p_hold (bins of 0.1)")
    most = max((float(r.count.max()) for _, r in curves), default=0.0)
    counts.set_ylim(COUNT_FLOOR, max(most, 1.0) * COUNT_HEADROOM)  # first: no autoscaling on the log axis
    counts.set_yscale("log")  # on a linear axis 890 trials in a bin beside 21,000 held-out labels drew no bar
    counts.set_ylabel("grasps (log)")
    counts.set_xticks(np.linspace(0, 1, 11))
    return fig
