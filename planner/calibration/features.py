"""The analytic measures a probability of holding is fitted on, as one table.

A *measure table* maps each name of :data:`MEASURES` to an ``(n,)`` float
array over n grasps (NaN: not measured). It is built from grasp records
(:func:`of_grasps`) or from stored columns (the database reads the same
names), so the fitted model sees the very numbers the store holds.

:func:`design` turns a table into the model's ``(n, k)`` inputs, one column
per entry of :data:`FEATURES`: each a monotone transform of one measure, with
a neutral value where it was not measured (:data:`FILL`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np

from planner.errors import InputError

if TYPE_CHECKING:
    from planner.grasp import Grasp

#: The raw measures read per grasp (units: epsilon, volume dimensionless; resist_* [g]; margins, width [m];
#: counts; force_closure 0/1; settled_epsilon dimensionless).
MEASURES = ("epsilon", "volume", "force_closure", "resist_worst", "resist_mean", "open_margin", "close_margin",
            "push", "width", "n_contacts", "links_touching", "settled_epsilon")

#: [m] margins above this are all "plenty of travel" (an untouched finger's margin is inf).
MARGIN_CAP = 0.04
#: [g] weight resistance is compared on a log scale: log1p(min(resist, cap)).
RESIST_CAP = 1e4

#: feature name -> (measure, transform); transforms are monotone so a coefficient's sign reads as a direction.
FEATURES: dict[str, tuple[str, str]] = {
    "epsilon": ("epsilon", "identity"),
    "force_closure": ("force_closure", "identity"),
    "log_resist_worst": ("resist_worst", "log_resist"),
    "log_resist_mean": ("resist_mean", "log_resist"),
    "open_margin": ("open_margin", "margin"),
    "close_margin": ("close_margin", "margin"),
    "push": ("push", "identity"),
    "width": ("width", "identity"),
    "n_contacts": ("n_contacts", "identity"),
    "links_touching": ("links_touching", "identity"),
    "settled_epsilon": ("settled_epsilon", "identity"),
}

#: Value of a feature whose measure was not computed (NaN): the "nothing known" end of its scale.
FILL = {"epsilon": 0.0, "force_closure": 0.0, "log_resist_worst": 0.0, "log_resist_mean": 0.0,
        "open_margin": MARGIN_CAP, "close_margin": MARGIN_CAP, "push": 0.0, "width": 0.0, "n_contacts": 0.0,
        "links_touching": 0.0, "settled_epsilon": 0.0}


def _transform(kind: str, x: np.ndarray) -> np.ndarray:
    if kind == "log_resist":
        return np.log1p(np.clip(x, 0.0, RESIST_CAP))
    if kind == "margin":
        return np.clip(x, 0.0, MARGIN_CAP)  # inf (no finger touching) -> the cap
    return x


def design(table: Mapping[str, np.ndarray], names: Sequence[str]) -> np.ndarray:
    """(n, len(names)) inputs of the features ``names`` (keys of :data:`FEATURES`)."""
    unknown = [n for n in names if n not in FEATURES]
    if unknown:
        raise InputError(f"unknown calibration feature(s) {', '.join(unknown)}; available: {', '.join(FEATURES)}")
    columns = []
    for name in names:
        measure, kind = FEATURES[name]
        raw = np.asarray(table[measure], float)
        x = _transform(kind, raw)
        columns.append(np.where(np.isnan(raw), FILL[name], x))
    n = len(np.asarray(table[FEATURES[names[0]][0]])) if names else 0
    return np.stack(columns, axis=1) if columns else np.zeros((n, 0))


def of_grasps(grasps: Sequence[Grasp]) -> dict[str, np.ndarray]:
    """The measure table of grasp records (NaN where a measure was not computed)."""
    nan = np.nan

    def measured(name: str) -> np.ndarray:
        return np.array([nan if g.measures is None or getattr(g.measures, name) is None
                         else getattr(g.measures, name) for g in grasps], float)

    return {"epsilon": np.array([g.epsilon for g in grasps], float),
            "volume": np.array([g.volume for g in grasps], float),
            "force_closure": np.array([float(g.force_closure) for g in grasps], float),
            "width": np.array([nan if g.width is None else g.width for g in grasps], float),
            "n_contacts": np.array([len(g.contacts) for g in grasps], float),
            "links_touching": np.array([g.contacts.touching for g in grasps], float),
            **{name: measured(name) for name in ("resist_worst", "resist_mean", "open_margin", "close_margin",
                                                 "push", "settled_epsilon")}}


def of_columns(col: Mapping[str, Sequence[object]]) -> dict[str, np.ndarray]:
    """The measure table of stored columns (None -> NaN); every name of :data:`MEASURES` must be there."""
    return {name: np.array([np.nan if v is None else v for v in col[name]], float) for name in MEASURES}
