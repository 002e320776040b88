"""``grasp calibrate``: fit p_hold to a labelled set and measure it held out.

:func:`calibrate` cross-validates the model over folds grouped by object
(nested choice of the penalty; :func:`planner.calibration.model.cross_validate`),
computes the held-out figures from the out-of-fold predictions, and fits the
final model on every grasp. Figures (over closed grasps; the ranking order is
the database's: force closure as planned or once squeezed first, then p_hold):

- ``auc_mean``: mean over objects of the per-object ROC AUC of p_hold (an
  object's files pooled); ``auc_width``: the same for "smaller closed width is
  better"; ``auc_pooled``: over all grasps;
- ``top10``: mean over files of the share of the 10 best-ranked grasps that hold;
- ``ece``: expected calibration error over deciles; ``log_loss``;
- ``<figure>_lo``, ``<figure>_hi`` for ``auc_mean``, ``top10``, ``ece`` and
  ``agreement`` (p_hold >= 0.5 against the label): the 95% interval of the
  figure over objects (a percentile bootstrap drawing objects, seeded:
  :func:`planner.calibration.metrics.object_figures`), how far another set of
  as many objects could move it.

Where the labelled set holds trial verdicts (``grasp calibrate --trial N``),
the model also gets the update of p_hold by that trial's verdict
(:mod:`planner.calibration.update`), fitted on the out-of-fold p_hold of
the tried grasps; figures over those grasps, the label as 1 or 0 against
the file's: ``trialled`` (how many), ``trial_agreement`` (the verdict alone),
``p_hold_agreement`` (p_hold >= 0.5) and ``p_hold_trial_agreement``
(p_hold_trial >= 0.5, the update itself fitted without the grasp's fold),
with its 95% interval over objects (``p_hold_trial_agreement_lo``, ``_hi``).
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from planner.calibration.labels import LabelledSet
from planner.calibration.metrics import (
    INTERVAL_SEED,
    Reliability,
    agreement,
    group_interval,
    object_figures,
    reliability,
    roc_auc,
)
from planner.calibration.model import (
    DEFAULT_FEATURES,
    DEFAULT_TREES,
    CrossValidation,
    LogisticModel,
    cross_validate,
    fit,
    log_loss,
)
from planner.calibration.trees import TreeSettings
from planner.calibration.update import fit_update
from planner.db.ranking import rank_order, ranks_first
from planner.errors import InputError

#: The k of "the k best-ranked grasps hold".
TOP_K = 10


@dataclass(frozen=True)
class Calibration:
    """A fitted model and its held-out figures.

    model: fitted on every grasp; cv: the out-of-fold predictions;
    figures: the held-out figures (module docstring); per_object: one dict per
    object (group, grasps, success rate, AUC of p_hold and of width);
    reliability: the held-out reliability table (deciles).
    """

    model: LogisticModel
    cv: CrossValidation
    figures: dict[str, float]
    per_object: list[dict]
    reliability: Reliability


def calibrate(data: LabelledSet, *, folds: int = 5, features: Sequence[str] = DEFAULT_FEATURES,
              source: str = "", trees: TreeSettings | None = DEFAULT_TREES) -> Calibration:
    """Cross-validate and fit p_hold on ``data`` (see the module docstring)."""
    objects = len(set(data.groups))
    if objects < 2:
        raise InputError(f"calibration needs labelled grasps of at least 2 objects (folds grouped by object), "
                         f"got {objects}")
    if len(set(data.labels.tolist())) < 2:
        raise InputError("calibration needs both outcomes among the labels (some grasps that hold, some that drop)")
    k = min(folds, objects)
    cv = cross_validate(data.table, data.labels, data.groups, data.hand, features=features, folds=k, trees=trees)
    l2 = float(np.exp(np.mean(np.log(cv.l2))))
    figures = held_out_figures(data, cv.p)
    figures["folds"] = float(k)
    model = fit(data.table, data.labels, data.hand, features=features, l2=l2, source=source, trees=trees)
    table = reliability(data.labels, cv.p)
    updates = {}
    if data.verdicts is not None and np.any(tried := ~np.isnan(data.verdicts)):
        figures.update(trial_figures(data, cv))
        updates[data.engine] = fit_update(data.engine, cv.p[tried], data.verdicts[tried], data.labels[tried])
    files = tuple(sorted(set(data.files)))
    hashes = tuple(data.hashes[f] for f in files) if all(f in data.hashes for f in files) else ()
    model = replace(model, source=source, figures={k_: v for k_, v in figures.items() if math.isfinite(v)},
                    held_out=table, updates=updates, domain=domain(data), labels=files, label_hashes=hashes)
    return Calibration(model, cv, figures, per_object(data, cv.p), table)


def domain(data: LabelledSet) -> dict[str, tuple[float, float]]:
    """(low, high) of each object property over the labelled set's files (empty where it does not say)."""
    used = set(data.files)
    values = [props for stem, props in data.objects.items() if stem in used]
    names = set.intersection(*(set(v) for v in values)) if values else set()
    return {k: (min(v[k] for v in values), max(v[k] for v in values)) for k in sorted(names)}


def trial_figures(data: LabelledSet, cv: CrossValidation) -> dict[str, float]:
    """Agreement with the labels of the tried grasps (module docstring); the
    update is fitted per fold on the other folds' tried grasps."""
    assert data.verdicts is not None
    tried = np.flatnonzero(~np.isnan(data.verdicts))
    y, v, p, fold = data.labels[tried], data.verdicts[tried], cv.p[tried], cv.fold[tried]
    q = np.full(len(tried), np.nan)
    for f in np.unique(fold):
        train, test = fold != f, fold == f
        if len(set(y[train].tolist())) == 2:
            q[test] = fit_update(data.engine, p[train], v[train], y[train]).apply(p[test], v[test])
    groups = np.asarray(data.groups)[tried]
    members = [np.flatnonzero(groups == g) for g in np.unique(groups)]

    def pooled(picked: np.ndarray) -> float:
        idx = np.concatenate([members[g] for g in picked])
        return agreement(y[idx], q[idx])

    lo, hi = group_interval(pooled, len(members), np.random.default_rng(INTERVAL_SEED))
    return {"trialled": float(len(tried)), "trial_agreement": float(np.mean(v == y)),
            "p_hold_agreement": float(np.mean((p >= 0.5) == (y == 1))),
            "p_hold_trial_agreement": agreement(y, q), "p_hold_trial_agreement_lo": lo,
            "p_hold_trial_agreement_hi": hi}


def per_object(data: LabelledSet, p: np.ndarray) -> list[dict]:
    rows = defaultdict(list)
    for i, g in enumerate(data.groups):
        rows[g].append(i)
    out = []
    for g, idx in sorted(rows.items()):
        idx_a = np.array(idx)
        y = data.labels[idx_a]
        out.append({"object": g, "grasps": len(idx), "success_rate": float(y.mean()),
                    "auc_p_hold": roc_auc(y, p[idx_a]),
                    "auc_width": roc_auc(y, -np.nan_to_num(data.table["width"][idx_a], nan=np.inf))})
    return out


def held_out_figures(data: LabelledSet, p: np.ndarray) -> dict[str, float]:
    objects = per_object(data, p)
    auc = [o["auc_p_hold"] for o in objects if math.isfinite(o["auc_p_hold"])]
    width = [o["auc_width"] for o in objects if math.isfinite(o["auc_width"])]
    tops, first = [], ranks_first(data.table)
    for stem in sorted(set(data.files)):
        idx = np.flatnonzero(np.array(data.files) == stem)
        order = rank_order(p[idx], first[idx])
        tops.append(float(np.mean(data.labels[idx][order[:TOP_K]])))
    return {"grasps": float(len(p)), "objects": float(len(objects)),
            "auc_mean": float(np.mean(auc)) if auc else math.nan,
            "auc_width": float(np.mean(width)) if width else math.nan,
            "auc_pooled": roc_auc(data.labels, p), "top10": float(np.mean(tops)),
            "ece": reliability(data.labels, p).ece, "log_loss": log_loss(data.labels, p),
            "agreement": agreement(data.labels, p),
            "success_rate": float(np.mean(data.labels)),
            **object_figures(data.labels, p, data.groups, data.files, first, TOP_K,
                             np.random.default_rng(INTERVAL_SEED))}
