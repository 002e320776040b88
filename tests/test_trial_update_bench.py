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


def test_compare_fits_a_trial_field_that_carries_signal_and_keeps_the_clamp() -> None:
    """Synthetic trials where the log of the closing motion, not the verdict, tells the label: fit_terms gives it a
    weight (negative: the more the object moved, the less it holds), and the out-of-sample agreement of the
    variant's p_hold_trial beats today's update's; the clamp holds (held never below p_hold, dropped never above)."""
    from trial_update import FULL_RECORD_START, apply_terms, fit_terms, trial_columns

    rng = np.random.default_rng(3)
    n = 4000
    moved = 10 ** rng.uniform(-4, -1, n)  # [m] closing motion
    y = (rng.random(n) < 1 / (1 + np.exp(3 * (np.log10(moved) + 2.5)))).astype(float)
    held = (rng.random(n) < 0.5 + 0.2 * (y - 0.5)).astype(float)
    p = np.full(n, 0.5) + rng.normal(0, 0.05, n)
    records = [[bool(h), "held" if h else "slipped", 0.0] + [m, 0.0, 0.0, 0.0, 2.0] for h, m in zip(held, moved)]
    assert FULL_RECORD_START == 3
    x = trial_columns(records)["log closing linear"][:, None]
    train, test = np.arange(n) < n // 2, np.arange(n) >= n // 2
    w = fit_terms(p[train], held[train], x[train], y[train])
    assert w[3] < -1.0
    q = apply_terms(w, p[test], held[test], x[test])
    w0 = fit_terms(p[train], held[train], np.zeros((int(train.sum()), 0)), y[train])
    q0 = apply_terms(w0, p[test], held[test], np.zeros((int(test.sum()), 0)))
    assert np.mean((q >= 0.5) == (y[test] == 1)) > np.mean((q0 >= 0.5) == (y[test] == 1)) + 0.1
    assert w[2] > 0
    assert np.all(q[held[test] > 0.5] >= p[test][held[test] > 0.5])
    assert np.all(q[held[test] < 0.5] <= p[test][held[test] < 0.5])
