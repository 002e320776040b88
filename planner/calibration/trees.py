"""The interaction term of p_hold: small regression trees boosted on top of
the additive logistic model (:mod:`planner.calibration.model`).

The additive model gives each feature its own part of the log-odds, so it
cannot say "a wide grasp holds only where the pads sit deep" (on the dev
set's FleX labels the trees added about one point of held-out AUC, more with
more poses: bench/RESULTS.md). The trees take the additive model's log-odds
as their starting point (gradient boosting with an initial margin, the
log-loss), so what they add is only what the sum of per-feature parts
missed; ``grasp best --explain`` shows it as one term, ``interactions``.

:class:`Trees` is the fitted term as a value (numpy only): every tree's
nodes in flat arrays. :func:`fit_trees` fits it with scikit-learn's
``GradientBoostingClassifier`` (imported only to fit, as scipy is for the
logistic part). The trees read the features' inputs as the additive part
does (``features.design``, each clipped to the fitting data's bounds),
before any spline column.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from planner.errors import InputError

#: A node without children (scikit-learn's TREE_LEAF).
LEAF = -1


@dataclass(frozen=True)
class TreeSettings:
    """How the trees are grown (scikit-learn's names): ``n_trees`` rounds of
    ``learning_rate``, each a tree of at most ``depth`` levels whose leaves
    hold at least ``min_leaf`` grasps, fitted on a ``subsample`` share of the
    grasps drawn with ``seed``; ``extra``: features (keys of
    :data:`~planner.calibration.features.FEATURES`) that only the trees read,
    after the model's own (the cells of ``local_sdf``)."""

    n_trees: int = 600
    depth: int = 3
    learning_rate: float = 0.05
    min_leaf: int = 100
    subsample: float = 0.8
    seed: int = 0
    extra: tuple[str, ...] = ()

    def __str__(self) -> str:  # a model's source line: a long run of cells named by its ends
        extra = self.extra if len(self.extra) <= 2 else f"{self.extra[0]}..{self.extra[-1]}"
        return (f"TreeSettings(n_trees={self.n_trees}, depth={self.depth}, learning_rate={self.learning_rate}, "
                f"min_leaf={self.min_leaf}, subsample={self.subsample}, seed={self.seed}"
                + (f", extra={extra}" if self.extra else "") + ")")

    def __post_init__(self) -> None:
        if self.n_trees < 1 or self.depth < 1 or self.min_leaf < 1:
            raise InputError("trees: n_trees, depth and min_leaf must be >= 1")
        if not 0 < self.learning_rate <= 1 or not 0 < self.subsample <= 1:
            raise InputError("trees: learning_rate and subsample must be in (0, 1]")


@dataclass(frozen=True)
class Trees:
    """Boosted regression trees over a model's feature inputs.

    roots : (t,) int, the first node of each tree; feature : (m,) int, the
    input column a node splits on (``LEAF`` at a leaf); threshold : (m,)
    [the input's units], a grasp goes left where its input (as float32,
    as the trees were grown) is <= it; left, right : (m,) int, the
    children (``LEAF`` at a leaf); value : (m,) a leaf's part of the
    log-odds, learning rate included (0 at inner nodes). The term is the
    sum over trees of the leaf each grasp reaches.
    """

    roots: np.ndarray
    feature: np.ndarray
    threshold: np.ndarray
    left: np.ndarray
    right: np.ndarray
    value: np.ndarray

    def __post_init__(self) -> None:
        ints = {k: np.asarray(getattr(self, k), np.int64) for k in ("roots", "feature", "left", "right")}
        floats = {k: np.asarray(getattr(self, k), float) for k in ("threshold", "value")}
        m = len(ints["feature"])
        if any(a.shape != (m,) for k, a in {**ints, **floats}.items() if k != "roots") or ints["roots"].ndim != 1:
            raise InputError("calibration model: trees' node arrays must be one-dimensional and of one length")
        inner = ints["left"] != LEAF
        children = np.r_[ints["left"][inner], ints["right"][inner], ints["roots"]]
        if ((ints["right"] != LEAF) != inner).any() or (children < 0).any() or (children >= m).any():
            raise InputError("calibration model: trees' children must be node indices (or -1 at both of a leaf's)")
        if (ints["feature"][inner] < 0).any() or not np.isfinite(floats["value"]).all():
            raise InputError("calibration model: trees' inner nodes need a feature; values must be finite")
        for k, a in {**ints, **floats}.items():
            object.__setattr__(self, k, a)

    @property
    def depth(self) -> int:
        """The longest path from a root to a leaf (edges)."""
        depth, level = 0, self.roots
        while True:
            inner = level[self.left[level] != LEAF]
            if not len(inner):
                return depth
            level, depth = np.r_[self.left[inner], self.right[inner]], depth + 1

    def evaluate(self, x: np.ndarray) -> np.ndarray:
        """(n,) the term for inputs ``x`` (n, k): every tree at once, one
        level per step (a leaf its own child both ways, :meth:`_walk`: no
        test of which nodes are inner; ~2x faster than with it, the same
        leaves, summed in the same order)."""
        x32 = np.ascontiguousarray(np.asarray(x, float).astype(np.float32))
        feature, children = self._walk
        threshold, roots = self.threshold, self.roots
        if len(x32) == 0 or len(roots) == 0:
            return self.value[np.zeros((len(x32), len(roots)), np.int64)].sum(axis=1)
        at = (np.arange(len(x32)) * x32.shape[1])[:, None]  # a row's start in the flat inputs
        flat = x32.ravel()
        # the first level reads one column per tree; node (n, t) kept C-ordered: the sum's order is the rows'
        node = np.ascontiguousarray(children[2 * roots + ~(x32[:, feature[roots]] <= threshold[roots])])
        for _ in range(self.depth - 1):
            node = children[2 * node + ~(flat[at + feature[node]] <= threshold[node])]
        return self.value[node].sum(axis=1)

    @cached_property
    def _walk(self) -> tuple[np.ndarray, np.ndarray]:
        """(m,) each node's split input (0 at a leaf) and (2 m,) its children, left then right (a leaf's both
        itself: a walk that reached it stays)."""
        leaf = self.left == LEAF
        own = np.arange(len(self.left))
        children = np.stack([np.where(leaf, own, self.left), np.where(leaf, own, self.right)], axis=1).ravel()
        return np.where(leaf, 0, self.feature), children

    def evaluate_reference(self, x: np.ndarray) -> np.ndarray:
        """:meth:`evaluate` one grasp and one tree at a time."""
        x32 = np.asarray(x, float).astype(np.float32)
        out = np.zeros(len(x32))
        for i, row in enumerate(x32):
            for node in self.roots:
                while self.left[node] != LEAF:
                    node = self.left[node] if row[self.feature[node]] <= self.threshold[node] else self.right[node]
                out[i] += self.value[node]
        return out

    def to_dict(self) -> dict[str, list]:
        return {"roots": self.roots.tolist(), "feature": self.feature.tolist(), "threshold": self.threshold.tolist(),
                "left": self.left.tolist(), "right": self.right.tolist(), "value": self.value.tolist()}

    @classmethod
    def from_dict(cls, data: Mapping) -> Trees:
        return cls(*(np.asarray(data[k]) for k in ("roots", "feature", "threshold", "left", "right", "value")))


def fit_trees(x: np.ndarray, labels: np.ndarray, margin: np.ndarray, settings: TreeSettings) -> Trees:
    """Trees that add to the log-odds ``margin`` (n,) of grasps with inputs
    ``x`` (n, k) and ``labels`` (n,) 0/1 what lowers their log-loss."""
    from sklearn.ensemble import GradientBoostingClassifier  # fitting only

    y = np.asarray(labels, int)
    gb = GradientBoostingClassifier(init=_Margin(x, np.asarray(margin, float)), n_estimators=settings.n_trees,
                                    max_depth=settings.depth, learning_rate=settings.learning_rate,
                                    min_samples_leaf=settings.min_leaf, subsample=settings.subsample,
                                    random_state=settings.seed)
    gb.fit(np.asarray(x, float), y)
    roots, parts, offset = [], [], 0
    for est in gb.estimators_[:, 0]:
        t = est.tree_
        inner = t.children_left != LEAF
        roots.append(offset)
        parts.append((np.where(inner, t.feature, LEAF), np.where(inner, t.threshold, 0.0),
                      np.where(inner, t.children_left + offset, LEAF), np.where(inner, t.children_right + offset, LEAF),
                      np.where(inner, 0.0, t.value[:, 0, 0] * settings.learning_rate)))
        offset += t.node_count
    return Trees(np.array(roots), *(np.concatenate(a) for a in zip(*parts)))


class _Margin:
    """scikit-learn's initial estimator for boosting from given log-odds:
    the grasps being fitted are ``x``'s rows, their log-odds ``margin``."""

    def __init__(self, x: np.ndarray, margin: np.ndarray) -> None:
        self._x, self._margin = np.asarray(x, float), margin

    def fit(self, x: np.ndarray, y: np.ndarray, sample_weight: np.ndarray | None = None) -> _Margin:
        return self

    def predict_proba(self, x: np.ndarray) -> np.ndarray:
        # scikit-learn hands back the fitted grasps, converted (float32): the same rows, in order
        if len(x) != len(self._margin) or not np.allclose(x, self._x, rtol=1e-6, atol=1e-6 * np.abs(self._x).max()):
            raise InputError("trees: the initial log-odds are known only for the grasps being fitted")
        p = 0.5 * (1.0 + np.tanh(0.5 * self._margin))
        return np.column_stack([1.0 - p, p])

    def get_params(self, deep: bool = True) -> dict:
        return {}
