"""The shared column definitions: a batch of :class:`~planner.grasp.Grasp`
records as columns, the one helper every format writes from.

:func:`grasp_columns` keys the columns by the record's field names (each
column is built when a writer first asks for it, so a format that writes a
few columns pays for those only); the validation and robust results are
flattened (``validation_success``, ..., ``robust_mean``, ``robust_quantile``,
``robust_samples``), and so are the analytic measures (``resist_worst``,
``resist_mean``, ``open_margin``, ``close_margin``, ``push``,
``settled_epsilon``: NaN when not measured; ``p_hold``: NaN where no model
applies; ``feasibility``: comma-separated reasons, '' when feasible). A
value that is absent holds NaN in a float column and
-1 in an integer column (``id`` and ``unit_id`` of a record not stored yet,
``rank``, ``validation_success``, ``validation_fingers_in_contact``,
``robust_samples``); ``width``, ``reachability`` and ``manipulability`` are
floats. Contacts and joints stay JSON text as stored (``[{point, normal,
link}]``, ``{joint: value}``); :func:`joint_matrix` decodes joints in one
parser call per batch.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from operator import attrgetter

import numpy as np

from planner.datasets.meshes import ExportedObject
from planner.db.store import json_list
from planner.grasp import Grasp

Column = np.ndarray | list
Builder = Callable[[Sequence[Grasp]], Column]


def _ints(name: str) -> Builder:
    return lambda gs: np.array([-1 if (v := getattr(g, name)) is None else v for g in gs], np.int64)


def _stack(name: str, shape: tuple[int, ...]) -> Builder:
    return lambda gs: np.array([getattr(g, name) for g in gs], float).reshape(len(gs), *shape)


def _texts(name: str) -> Builder:
    return lambda gs: [getattr(g, name).json_text() for g in gs]


def _trial(name: str, absent: float, dtype: type) -> Builder:
    return lambda gs: np.array([absent if g.validation is None else getattr(g.validation, name) for g in gs], dtype)


def _measure(name: str) -> Builder:
    return lambda gs: np.array([math.nan if g.measures is None else getattr(g.measures, name) for g in gs], float)


def _robust(name: str, absent: float, dtype: type) -> Builder:
    return lambda gs: np.array([absent if g.robust is None else getattr(g.robust, name) for g in gs], dtype)


#: Plain fields read together, in one pass over the records: (name, dtype).
SCALARS = (("candidate", np.int64), ("seed", np.int64), ("roll", float), ("standoff", float), ("epsilon", float),
           ("volume", float), ("score", float), ("force_closure", np.int64), ("width", float),
           ("reachability", float), ("manipulability", float), ("p_hold", float))


#: column -> how to build it from n records (besides SCALARS).
BUILDERS: dict[str, Builder] = {
    **{name: _ints(name) for name in ("id", "unit_id", "rank")},
    "preshape": lambda gs: [g.preshape for g in gs],
    "approach_point": _stack("approach_point", (3,)),
    "approach_dir": _stack("approach_dir", (3,)),
    "pose": _stack("pose", (4, 4)),
    **{name: _texts(name) for name in ("contacts", "open_joints", "closed_joints")},
    "n_contacts": lambda gs: np.array([len(g.contacts) for g in gs], np.int64),
    "links_touching": lambda gs: np.array([g.contacts.touching for g in gs], np.int64),
    "validation_success": _trial("success", -1, np.int64),
    "validation_fingers_in_contact": _trial("fingers_in_contact", -1, np.int64),
    **{f"validation_{stage}_{kind}": _trial(f"{stage}_{kind}", math.nan, float)
       for stage in ("closing", "shaking") for kind in ("linear", "angular")},
    "robust_mean": _robust("mean", math.nan, float),
    "robust_quantile": _robust("quantile", math.nan, float),
    "robust_samples": _robust("samples", -1, np.int64),
    **{name: _measure(name) for name in ("resist_worst", "resist_mean", "open_margin", "close_margin", "push",
                                         "settled_epsilon")},
    "feasibility": lambda gs: ["" if g.measures is None else ",".join(g.measures.reasons) for g in gs],
}


class GraspColumns(Mapping[str, Column]):
    """n records as columns, each built on first use and kept."""

    def __init__(self, grasps: Sequence[Grasp]) -> None:
        self.grasps = grasps
        self._built: dict[str, Column] = {}

    def __getitem__(self, name: str) -> Column:
        if name not in self._built:
            if name in _SCALAR_TYPES:
                self._scalars()
            else:
                self._built[name] = BUILDERS[name](self.grasps)
        return self._built[name]

    def _scalars(self) -> None:
        names = [name for name, _ in SCALARS]
        values = zip(*map(attrgetter(*names), self.grasps)) if self.grasps else ([] for _ in names)
        for (name, dtype), column in zip(SCALARS, values):
            self._built[name] = np.array(column, dtype)  # None -> NaN in float columns

    def __iter__(self) -> Iterator[str]:
        return iter([*_SCALAR_TYPES, *BUILDERS])

    def __len__(self) -> int:
        return len(_SCALAR_TYPES) + len(BUILDERS)


_SCALAR_TYPES = dict(SCALARS)


def grasp_columns(grasps: Sequence[Grasp]) -> GraspColumns:
    """The columns of n records (see the module docstring)."""
    return GraspColumns(grasps)


def joint_matrix(texts: Sequence[str], names: Sequence[str]) -> np.ndarray:
    """(n, J) joint values [rad or m] of n JSON texts ``{joint: value}``, in
    the order of ``names``; NaN where absent."""
    rows = json_list(texts)
    return np.array([[row.get(k, math.nan) for k in names] for row in rows], float).reshape(len(rows), len(names))


@dataclass(frozen=True)
class Stream:
    """The selected grasps of one (object, hand), as batches read on demand."""

    info: ExportedObject
    hand: str
    batches: Iterator[list[Grasp]]
