"""How well a probability of holding predicts labels: ROC AUC, expected
calibration error, the reliability table, and folds grouped by object.

Inputs are ``labels`` (n,) 0/1 (NaN: unlabelled, left out) and predictions
``p`` (n,) in [0, 1] (or any score, for the AUC).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

#: Bins of the reliability table and of the ECE: deciles of predicted probability.
BINS = 10


def roc_auc(labels: np.ndarray, scores: np.ndarray) -> float:
    """ROC AUC of ``scores`` (n,) for binary ``labels`` (n,) (NaN: unlabelled,
    left out); a NaN score (not computed) ranks lowest; ties count half.
    NaN when a class is missing or no grasp has the score (never computed:
    not the 0.5 of a useless score)."""
    from scipy.stats import rankdata

    y, x = np.asarray(labels, float), np.asarray(scores, float)
    keep = np.isfinite(y)
    if not np.isfinite(x[keep]).any():
        return math.nan
    y, x = y[keep] > 0.5, np.nan_to_num(x[keep], nan=-np.inf, neginf=-np.inf, posinf=np.inf)
    pos, neg = int(y.sum()), int((~y).sum())
    if pos == 0 or neg == 0:
        return math.nan
    ranks = rankdata(x)
    return float((ranks[y].sum() - pos * (pos + 1) / 2) / (pos * neg))


@dataclass(frozen=True)
class Reliability:
    """Predicted vs observed success per bin of predicted probability.

    edges (BINS + 1,) bin edges in [0, 1]; predicted (BINS,) mean prediction
    of each bin, observed (BINS,) success rate, count (BINS,) grasps (NaN
    means where a bin is empty).
    """

    edges: np.ndarray
    predicted: np.ndarray
    observed: np.ndarray
    count: np.ndarray

    def __post_init__(self) -> None:
        k = len(self.edges) - 1
        if any(len(a) != k for a in (self.predicted, self.observed, self.count)):
            raise ValueError("Reliability: predicted, observed and count must have len(edges) - 1 entries")

    @property
    def ece(self) -> float:
        """Expected calibration error: sum over bins of |predicted - observed| x share of grasps."""
        n = self.count.sum()
        if n == 0:
            return math.nan
        full = self.count > 0
        return float(np.sum(np.abs(self.predicted[full] - self.observed[full]) * self.count[full]) / n)


def reliability(labels: np.ndarray, p: np.ndarray, bins: int = BINS) -> Reliability:
    """The reliability table of predictions ``p`` (n,) for ``labels`` (n,), ``bins`` equal-width bins."""
    y, q = np.asarray(labels, float), np.clip(np.asarray(p, float), 0.0, 1.0)
    keep = np.isfinite(y) & np.isfinite(q)
    y, q = y[keep], q[keep]
    edges = np.linspace(0.0, 1.0, bins + 1)
    which = np.clip(np.searchsorted(edges, q, side="right") - 1, 0, bins - 1)
    count = np.bincount(which, minlength=bins).astype(float)
    with np.errstate(invalid="ignore", divide="ignore"):
        predicted = np.bincount(which, q, bins) / count
        observed = np.bincount(which, y, bins) / count
    return Reliability(edges, predicted, observed, count)


def expected_calibration_error(labels: np.ndarray, p: np.ndarray, bins: int = BINS) -> float:
    """ECE of ``p`` (n,) against ``labels`` (n,) over ``bins`` equal-width bins."""
    return reliability(labels, p, bins).ece


def grouped_folds(groups: Sequence[str], k: int) -> list[np.ndarray]:
    """``k`` test-index arrays partitioning range(n), each group (object id) in
    exactly one fold: groups sorted by name and dealt round-robin, largest
    first, so folds are balanced and the split does not depend on row order."""
    names = np.asarray(groups)
    unique, counts = np.unique(names, return_counts=True)
    if k < 2 or k > len(unique):
        raise ValueError(f"need 2 <= folds <= groups ({len(unique)}), got {k}")
    order = sorted(range(len(unique)), key=lambda i: (-counts[i], unique[i]))
    fold_of = {unique[i]: j % k for j, i in enumerate(order)}
    assigned = np.array([fold_of[g] for g in names])
    return [np.flatnonzero(assigned == f) for f in range(k)]
