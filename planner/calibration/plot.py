"""The reliability diagram: predicted vs observed success per decile of p_hold (PNG, matplotlib)."""

from __future__ import annotations

import io
from collections.abc import Sequence

import numpy as np

from planner.calibration.metrics import Reliability


def reliability_png(curves: Sequence[tuple[str, Reliability]], title: str) -> bytes:
    """A PNG of one or more reliability tables (label, table): observed success
    against mean predicted p_hold per bin, the diagonal being perfect
    calibration, and the grasps per bin below."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, counts) = plt.subplots(2, 1, figsize=(5, 5.6), gridspec_kw={"height_ratios": [3, 1]}, sharex=True)
    ax.plot([0, 1], [0, 1], color="0.6", linestyle="--", linewidth=1, label="perfect calibration")
    width = 0.1 / max(len(curves), 1)
    for k, (label, r) in enumerate(curves):
        full = r.count > 0
        ax.plot(r.predicted[full], r.observed[full], marker="o", label=f"{label} (ECE {r.ece:.3f})")
        centres = (r.edges[:-1] + r.edges[1:]) / 2
        counts.bar(centres - 0.05 + width * (k + 0.5), r.count, width=width * 0.9, label=label)
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    ax.set_ylabel("observed success rate")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7, loc="best")  # where it covers the fewest points: no corner is empty for every curve
    counts.set_xlabel("predicted p_hold (bins of 0.1)")
    counts.set_ylabel("grasps")
    counts.set_xticks(np.linspace(0, 1, 11))
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100)
    plt.close(fig)
    return buffer.getvalue()
