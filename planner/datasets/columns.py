"""The shared column definitions: a batch of :class:`~planner.grasp.Grasp`
records as columns, the one helper every format writes from.

:func:`grasp_columns` keys the columns by the record's field names; the
validation and robust results are flattened (``validation_success``, ...,
``robust_mean``, ``robust_quantile``, ``robust_samples``). A value that is
absent holds NaN in a float column and -1 in an integer column (``id`` and
``unit_id`` of a record not stored yet, ``rank``, ``validation_success``,
``validation_fingers_in_contact``, ``robust_samples``); ``width``,
``reachability`` and ``manipulability`` are floats. Contacts stay JSON text (``[{point, normal, link}]``), joints dicts.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from planner.db.store import ObjectRow
from planner.grasp import Grasp

Column = np.ndarray | list

#: Record fields copied as they are: (name, numpy dtype or None for a list).
_PLAIN = (("preshape", None), ("candidate", np.int64), ("seed", np.int64),
          ("roll", float), ("standoff", float), ("open_joints", None), ("closed_joints", None), ("epsilon", float),
          ("volume", float), ("force_closure", np.int64), ("score", float))
_OPTIONAL_FLOATS = ("width", "reachability", "manipulability")
_TRIAL = ("closing_linear", "closing_angular", "shaking_linear", "shaking_angular")


@dataclass(frozen=True)
class Stream:
    """The selected grasps of one (object, hand), as batches read on demand."""

    info: ObjectRow
    hand: str
    batches: Iterator[list[Grasp]]


def grasp_columns(grasps: Sequence[Grasp]) -> dict[str, Column]:
    """n records as columns: (n,) arrays, (n, 3) / (n, 4, 4) for vectors and
    poses, lists for strings and joint dicts (see the module docstring)."""
    n = len(grasps)
    out: dict[str, Column] = {name: np.array([_int(getattr(g, name)) for g in grasps], np.int64)
                              for name in ("id", "unit_id", "rank")}
    for name, dtype in _PLAIN:
        values = [getattr(g, name) for g in grasps]
        out[name] = values if dtype is None else np.array(values, dtype)
    for name in _OPTIONAL_FLOATS:
        out[name] = np.array([getattr(g, name) for g in grasps], float)  # None -> NaN
    out["approach_point"] = np.array([g.approach_point for g in grasps], float).reshape(n, 3)
    out["approach_dir"] = np.array([g.approach_dir for g in grasps], float).reshape(n, 3)
    out["pose"] = np.array([g.pose for g in grasps], float).reshape(n, 4, 4)
    out["contacts"] = [g.contacts.json_text() for g in grasps]
    out["n_contacts"] = np.array([len(g.contacts) for g in grasps], np.int64)
    out["links_touching"] = np.array([g.contacts.touching for g in grasps], np.int64)
    trials = [g.validation for g in grasps]
    out["validation_success"] = np.array([-1 if t is None else int(t.success) for t in trials], np.int64)
    out["validation_fingers_in_contact"] = np.array([-1 if t is None else t.fingers_in_contact for t in trials],
                                                    np.int64)
    for name in _TRIAL:
        out[f"validation_{name}"] = np.array([math.nan if t is None else getattr(t, name) for t in trials], float)
    robust = [g.robust for g in grasps]
    out["robust_mean"] = np.array([math.nan if r is None else r.mean for r in robust], float)
    out["robust_quantile"] = np.array([math.nan if r is None else r.quantile for r in robust], float)
    out["robust_samples"] = np.array([-1 if r is None else r.samples for r in robust], np.int64)
    return out


def _int(value: int | None) -> int:
    return -1 if value is None else value


def joint_matrix(joints: Sequence[dict[str, float]], names: Sequence[str]) -> np.ndarray:
    """(n, J) joint values [rad or m] in the order of ``names``; NaN where absent."""
    return np.array([[row.get(k, math.nan) for k in names] for row in joints], float).reshape(len(joints), len(names))
