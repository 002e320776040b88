"""How well a probability of holding predicts labels: ROC AUC, expected
calibration error, the reliability table, and folds grouped by object.

Inputs are ``labels`` (n,) 0/1 (NaN: unlabelled, left out) and predictions
``p`` (n,) in [0, 1] (or any score, for the AUC).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from planner.db.ranking import rank_order

#: Bins of the reliability table and of the ECE: deciles of predicted probability.
BINS = 10
#: Draws of the bootstrap over objects (:func:`group_interval`), its level, and the seed the figures use.
DRAWS = 2000
LEVEL = 0.95
INTERVAL_SEED = 0


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


def group_interval(statistic: Callable[[np.ndarray], float], groups: int, rng: np.random.Generator,
                   draws: int = DRAWS, level: float = LEVEL) -> tuple[float, float]:
    """(lo, hi): the percentile bootstrap interval at ``level`` of a figure over ``groups`` objects.

    ``statistic(picked)`` is the figure over the objects ``picked`` ((groups,) int indices in
    range(groups), repeats allowed); it is taken over ``draws`` draws of as many objects with replacement
    (what another set of as many objects of the same kind might give: an object's grasps are not
    independent of each other, so objects are drawn, not grasps). Draws whose figure is not finite are
    left out; (NaN, NaN) when none is finite or there are no objects."""
    if groups < 1 or draws < 1 or not 0.0 < level < 1.0:
        return math.nan, math.nan
    values = np.array([statistic(rng.integers(0, groups, groups)) for _ in range(draws)], float)
    values = values[np.isfinite(values)]
    if not len(values):
        return math.nan, math.nan
    lo, hi = np.quantile(values, [(1.0 - level) / 2.0, (1.0 + level) / 2.0])
    return float(lo), float(hi)


def object_figures(labels: np.ndarray, p: np.ndarray, groups: Sequence[str], files: Sequence[str],
                   first: np.ndarray, top_k: int, rng: np.random.Generator) -> dict[str, float]:
    """Intervals over objects (:func:`group_interval`) of the held-out figures of ``p`` (n,) for ``labels``
    (n,), grasps of objects ``groups`` (n,) in files ``files`` (n,): ``auc_mean`` (mean per-object ROC AUC),
    ``top10`` (mean over files of the share of the ``top_k`` best-ranked that hold, ``first`` (n,)
    first: :func:`planner.db.ranking.ranks_first`, force closure as planned or once squeezed), ``ece``
    and ``agreement`` (p >= 0.5 against the label, over grasps); each as ``<name>_lo`` and ``<name>_hi``. A NaN
    in ``p`` (a grasp not scored) ranks last and counts in neither ECE nor agreement."""
    y, q = np.asarray(labels, float), np.asarray(p, float)
    names, owner = np.unique(np.asarray(groups), return_inverse=True)
    members = [np.flatnonzero(owner == g) for g in range(len(names))]
    auc = np.array([roc_auc(y[m], q[m]) for m in members])
    stems = np.asarray(files)
    tops: list[list[float]] = [[] for _ in names]
    for stem in np.unique(stems):
        idx = np.flatnonzero(stems == stem)
        order = rank_order(q[idx], np.asarray(first)[idx])
        tops[owner[idx[0]]].append(float(np.mean(y[idx][order[:top_k]])))

    def pooled(picked: np.ndarray) -> np.ndarray:
        return np.concatenate([members[g] for g in picked])

    stats: dict[str, Callable[[np.ndarray], float]] = {
        "auc_mean": lambda picked: float(np.nanmean(auc[picked])) if np.isfinite(auc[picked]).any() else math.nan,
        "top10": lambda picked: float(np.mean([t for g in picked for t in tops[g]])),
        "ece": lambda picked: reliability(y[pooled(picked)], q[pooled(picked)]).ece,
        "agreement": lambda picked: agreement(y[pooled(picked)], q[pooled(picked)]),
    }
    out = {}
    for name, statistic in stats.items():
        out[f"{name}_lo"], out[f"{name}_hi"] = group_interval(statistic, len(names), rng)
    return out


def agreement(labels: np.ndarray, p: np.ndarray) -> float:
    """Share of the grasps with a finite ``p`` where p >= 0.5 matches the label (NaN if none)."""
    keep = np.isfinite(p)
    return float(np.mean((p[keep] >= 0.5) == (labels[keep] > 0.5))) if keep.any() else math.nan
