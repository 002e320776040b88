"""bench/trial_update.py's top-10 ranks as the database does: force closure as planned or once squeezed first."""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))

from trial_update import score_figures  # noqa: E402

from planner.calibration.labels import LabelledSet  # noqa: E402


def test_the_top_10_puts_first_the_poses_force_closure_once_squeezed() -> None:
    """Ten poses with the higher scores, not force closure even once squeezed, all dropped; two force closure only
    once squeezed, held: both are among the 10 best-ranked (2 of 10 hold), not left out (0 of 10)."""
    squeezed = np.array([0.0] * 10 + [1.0, 1.0])
    table = {"force_closure": np.zeros(12), "squeezed_force_closure": squeezed}
    data = LabelledSet(table, squeezed.copy(), ("o",) * 12, ("f",) * 12, "panda")
    _, top, _ = score_figures(data, np.where(squeezed > 0, 0.1, 0.9))
    assert top == 0.2
