"""A calibrated probability of holding, ``p_hold``, from the analytic measures.

The model is a logistic regression on standardised features
(:mod:`planner.calibration.features`) with an L2 penalty on the
coefficients (not the intercept), fitted by L-BFGS on the mean log-loss::

    z = (x - mean) / scale;   p_hold = 1 / (1 + exp(-(intercept + z . coef)))

A feature with knots enters as a restricted cubic spline (Harrell's: cubic
between its knots, linear beyond the outer ones, so a new object's values
outside the training range are extrapolated by a line, not a cubic): its
input x and one column per inner knot (:func:`spline_basis`), each with its
own coefficient. Beyond the range of the fitting data (``bounds``) an
input is held at the nearest end: a line fitted on nothing out there would
otherwise drive p_hold to 0 or 1 with certainty it never earned. That part
stays additive, one term per feature (a generalised additive model), so
``--explain`` still gives each feature's part of the log-odds; with
``trees``, boosted regression trees then add what the sum of per-feature
parts misses (:mod:`planner.calibration.trees`), shown as one more term,
``interactions``.

:func:`fit` fits one; :func:`cross_validate` gives out-of-fold predictions
over folds grouped by object, choosing the penalty inside each training
fold (nested), so the figures it yields are held-out ones. A model is a
frozen value stored as TOML (the shipped default, ``calibration/<hand>.toml``
beside ``hands/``) or as JSON in a database (:mod:`planner.db.store`).

The value :class:`LogisticModel` and its files live in
:mod:`~planner.calibration.logistic`, its columns (splines, bounds) in
:mod:`~planner.calibration.basis`; both are re-exported here.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from planner.calibration.basis import (  # noqa: F401 - re-exported
    KNOT_QUANTILES,
    KNOTS,
    MIN_SCALE,
    choose_knots,
    clip,
    columns,
    expand,
    fitting_bounds,
    spline_basis,
)
from planner.calibration.features import LOCAL, design
from planner.calibration.logistic import (  # noqa: F401 - re-exported
    FOLDER,
    SHIPPED_ENV,
    LogisticModel,
    _sigmoid,
    default_model,
    load_model,
)
from planner.calibration.metrics import grouped_folds
from planner.calibration.trees import TreeSettings, fit_trees
from planner.errors import InputError

#: The features a model uses unless told otherwise.
DEFAULT_FEATURES = ("epsilon", "force_closure", "log_resist_worst", "log_resist_mean", "open_margin", "close_margin",
                    "push", "width", "n_contacts", "links_touching", "settled_epsilon", "depth", "log_pad_area",
                    "pad_alignment", "opposition", "log_jaw_fill", "palm_gap", "com_lever", "com_height",
                    "gravity_arm", "torque_per_mu")
#: The features that enter as splines unless told otherwise (:func:`spline_basis`).
DEFAULT_SPLINES = ("epsilon", "log_resist_worst", "open_margin", "push", "width", "depth", "log_pad_area",
                   "pad_alignment", "opposition", "log_jaw_fill", "palm_gap", "com_lever", "com_height",
                   "gravity_arm", "torque_per_mu")
#: L2 penalties tried by cross-validation (per grasp of the mean log-loss, on standardised features).
L2_GRID = (1e-4, 1e-3, 1e-2, 1e-1, 1.0)
#: The interaction trees unless told otherwise (chosen by grouped CV on the dev set's tuning objects:
#: bench/RESULTS.md, 2026-12-03), reading the cells of local_sdf too (2026-12-05); None: an additive model alone.
DEFAULT_TREES: TreeSettings | None = TreeSettings(extra=LOCAL)


def fit(table: Mapping[str, np.ndarray], labels: np.ndarray, hand: str, *,
        features: Sequence[str] = DEFAULT_FEATURES, l2: float = 1e-2, source: str = "",
        splines: Sequence[str] = DEFAULT_SPLINES, trees: TreeSettings | None = None) -> LogisticModel:
    """The model minimising mean log-loss + ``l2``/2 |coef|^2 on grasps with
    ``labels`` (n,) 0/1; the ``splines`` among ``features`` get knots from
    these grasps (:func:`choose_knots`); ``trees``: then the interaction
    trees boosted from its log-odds (:func:`~planner.calibration.trees.fit_trees`)."""
    y = np.asarray(labels, float)
    raw = design(table, features)
    knots = choose_knots(raw, features, splines)
    x = expand(raw, features, knots)
    if len(y) != len(x) or len(y) == 0:
        raise InputError(f"calibration: {len(y)} labels for {len(x)} grasps; need at least one of each")
    if l2 < 0:
        raise InputError(f"calibration: l2 must be >= 0, got {l2}")
    mean = x.mean(axis=0)
    spread = x.std(axis=0)
    scale = np.where(spread > MIN_SCALE, spread, 1.0)
    z = (x - mean) / scale
    w0 = np.zeros(z.shape[1] + 1)
    rate = float(np.clip(y.mean(), 1e-6, 1 - 1e-6))
    w0[0] = math.log(rate / (1 - rate))
    from scipy.optimize import minimize  # fitting only: reading and applying a model needs numpy alone

    res = minimize(_loss, w0, args=(z, y, l2), jac=True, method="L-BFGS-B", options={"maxiter": 2000})
    model = LogisticModel(hand, tuple(features), mean, scale, res.x[1:], float(res.x[0]), float(l2), source,
                          knots=knots, bounds=fitting_bounds(raw, features))
    if trees is None or len(set(y.tolist())) < 2:
        return model
    model = replace(model, tree_features=tuple(trees.extra))
    model = replace(model, tree_turns=tree_turns(hand, len(features), model.tree_features))
    inputs, views = model.tree_inputs(table), 1 + len(model.tree_turns)
    grown = np.vstack([inputs, *(inputs[:, list(t)] for t in model.tree_turns)])
    # every grasp in each of its views, a leaf holding as many grasps' worth as without them
    settings = replace(trees, min_leaf=trees.min_leaf * views)
    return replace(model, trees=fit_trees(grown, np.tile(y, views), np.tile(model.logit(table), views), settings))


def tree_turns(hand: str, features: int, tree_features: Sequence[str]) -> tuple[tuple[int, ...], ...]:
    """The orders of the trees' inputs (``features`` columns of the model's
    own, then ``tree_features``) in which the ``hand`` turned onto itself
    sees the same grasp (:attr:`~planner.specs.hand_spec.HandSpec.cell_turns`):
    each cell of ``local_sdf`` among ``tree_features`` moved to the cell it
    turns into, everything else in place; none where the trees read no cell
    or a cell's turned twin is not among them."""
    if not set(tree_features) & set(LOCAL):
        return ()
    from planner.specs.hands import load_hand

    at = {name: i for i, name in enumerate(tree_features)}
    out = []
    for turn in load_hand(hand).cell_turns:
        twin = {LOCAL[i]: LOCAL[j] for i, j in enumerate(turn)}
        if all(twin.get(f, f) in at for f in tree_features):
            out.append(tuple(range(features)) + tuple(features + at[twin.get(f, f)] for f in tree_features))
    return tuple(out)


def _loss(w: np.ndarray, z: np.ndarray, y: np.ndarray, l2: float) -> tuple[float, np.ndarray]:
    """Mean log-loss + l2/2 |coef|^2 and its gradient; w = (intercept, coef...)."""
    s = w[0] + z @ w[1:]
    # log(1 + e^s) - y s, stable for large |s|
    loss = np.mean(np.logaddexp(0.0, s) - y * s) + 0.5 * l2 * float(w[1:] @ w[1:])
    r = (_sigmoid(s) - y) / len(y)
    grad = np.concatenate([[r.sum()], z.T @ r + l2 * w[1:]])
    return float(loss), grad


@dataclass(frozen=True)
class CrossValidation:
    """Out-of-fold predictions: p (n,) each grasp's p_hold from the model fitted
    without its object's fold; fold (n,) the fold of each grasp; l2 (folds,)
    the penalty each fold's inner cross-validation chose."""

    p: np.ndarray
    fold: np.ndarray
    l2: np.ndarray


def _subset(table: Mapping[str, np.ndarray], rows: np.ndarray) -> dict[str, np.ndarray]:
    return {k: np.asarray(v)[rows] for k, v in table.items()}


def log_loss(labels: np.ndarray, p: np.ndarray) -> float:
    q = np.clip(p, 1e-12, 1 - 1e-12)
    return float(-np.mean(labels * np.log(q) + (1 - labels) * np.log(1 - q)))


def choose_l2(table: Mapping[str, np.ndarray], labels: np.ndarray, groups: Sequence[str], hand: str, *,
              features: Sequence[str] = DEFAULT_FEATURES, folds: int = 5, grid: Sequence[float] = L2_GRID,
              splines: Sequence[str] = DEFAULT_SPLINES) -> float:
    """The penalty of ``grid`` with the least grouped-CV log-loss (ties: the larger)."""
    k = min(folds, len(set(groups)))
    if k < 2 or len(set(grid)) == 1:  # nothing to choose between: no inner CV (it cost 5 fits a penalty)
        return float(max(grid))
    tests = grouped_folds(groups, k)
    best, best_loss = float(max(grid)), math.inf
    for l2 in sorted(grid, reverse=True):
        p = np.empty(len(labels))
        for test in tests:
            train = np.setdiff1d(np.arange(len(labels)), test)
            p[test] = fit(_subset(table, train), labels[train], hand, features=features, l2=l2,
                          splines=splines).predict(_subset(table, test))
        loss = log_loss(labels, p)
        if loss < best_loss - 1e-9:
            best, best_loss = float(l2), loss
    return best


def cross_validate(table: Mapping[str, np.ndarray], labels: np.ndarray, groups: Sequence[str], hand: str, *,
                   features: Sequence[str] = DEFAULT_FEATURES, folds: int = 5,
                   grid: Sequence[float] = L2_GRID, splines: Sequence[str] = DEFAULT_SPLINES,
                   trees: TreeSettings | None = DEFAULT_TREES) -> CrossValidation:
    """Out-of-fold p_hold over ``folds`` folds grouped by ``groups`` (n,) (object ids); the penalty is chosen
    (additive model alone) inside each training fold, then that fold's model gets its ``trees``."""
    y = np.asarray(labels, float)
    groups = list(groups)
    tests = grouped_folds(groups, folds)
    p, fold, chosen = np.empty(len(y)), np.empty(len(y), int), []
    for f, test in enumerate(tests):
        train = np.setdiff1d(np.arange(len(y)), test)
        sub = _subset(table, train)
        l2 = choose_l2(sub, y[train], [groups[i] for i in train], hand, features=features, folds=folds, grid=grid,
                       splines=splines)
        chosen.append(l2)
        p[test] = fit(sub, y[train], hand, features=features, l2=l2, splines=splines,
                      trees=trees).predict(_subset(table, test))
        fold[test] = f
    return CrossValidation(p, fold, np.array(chosen))
