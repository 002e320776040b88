"""The shared column definitions: a batch of :class:`~planner.record.grasp.Grasp`
records as columns, the one helper every format writes from.

:func:`grasp_columns` keys the columns by the flat names of the declared
fields (:func:`planner.record.fields.record_fields`: the record's own, its
contact counts, its analytic measures, ``validation_*`` and ``robust_*``);
each column is built when a writer first asks for it, so a format that
writes a few columns pays for those only. A value that is absent holds the
field's neutral value: NaN in a float column, -1 in an integer column (``id``
and ``unit_id`` of a record not stored yet, ``rank``, ``validation_success``,
...), '' in a text column (``feasibility``, ``validation_reason``). Contacts
and joints stay JSON text as stored (``[{point, normal, link}]``, ``{joint:
value}``); :func:`joint_matrix` decodes joints in one parser call per batch.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from operator import attrgetter

import numpy as np

from planner.datasets.meshes import ExportedObject
from planner.db.store import json_list
from planner.record.fields import Field, getter, record_fields
from planner.record.grasp import Grasp
from planner.specs.hands import HandSpec

Column = np.ndarray | list
Builder = Callable[[Sequence[Grasp]], Column]


def _array(f: Field) -> Builder:
    """A field as an (n, ...) array, its neutral value where absent."""
    get, dtype, neutral = getter(f), DTYPES[f.dtype], f.neutral
    shape = f.shape
    if f.kind == "bool":
        return lambda gs: np.array([neutral if (v := get(g)) is None else int(v) for g in gs], dtype)
    if shape:
        absent = np.full(shape, neutral, dtype)  # a vector that may be absent (the table plane): NaN
        return lambda gs: np.array([absent if (v := get(g)) is None else v for g in gs], dtype).reshape(len(gs),
                                                                                                         *shape)
    return lambda gs: np.array([neutral if (v := get(g)) is None else v for g in gs], dtype)


def _strings(f: Field) -> Builder:
    get, neutral = getter(f), f.neutral
    if f.kind in ("joints", "contacts"):
        return lambda gs: [get(g).json_text() for g in gs]  # type: ignore[attr-defined]
    if f.kind == "reasons":
        return lambda gs: [neutral if (v := get(g)) is None else ",".join(v) for g in gs]  # type: ignore[arg-type]
    return lambda gs: [neutral if (v := get(g)) is None else v for g in gs]


DTYPES = {"float64": float, "int64": np.int64}

#: Plain fields of the record itself, read together in one pass over the records: (name, dtype).
SCALARS = tuple((f.name, DTYPES[f.dtype]) for f in record_fields() if "." not in f.attr and f.kind in ("real", "bool"))

#: column -> how to build it from n records (besides SCALARS).
BUILDERS: dict[str, Builder] = {f.name: _strings(f) if f.dtype == "string" else _array(f)
                                for f in record_fields() if f.name not in dict(SCALARS)}


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


def joint_matrix(texts: Sequence[str], names: Sequence[str], hand: HandSpec | None = None) -> np.ndarray:
    """(n, J) joint values [rad or m] of n JSON texts ``{joint: value}``, in
    the order of ``names``; with ``hand``, the mimics a text leaves out at
    their coupling (:meth:`~planner.specs.hands.HandSpec.posture`); NaN where absent."""
    rows = json_list(texts)
    if hand is not None:
        rows = [hand.posture(row) for row in rows]
    return np.array([[row.get(k, math.nan) for k in names] for row in rows], float).reshape(len(rows), len(names))


def given_matrix(texts: Sequence[str], names: Sequence[str]) -> np.ndarray:
    """(n, J) 1 where each of n JSON texts ``{joint: value}`` gives joint ``names[j]``, 0 where it does not (a
    mimic :func:`joint_matrix` fills in with ``hand``)."""
    rows = json_list(texts)
    return np.array([[k in row for k in names] for row in rows], np.int64).reshape(len(rows), len(names))


@dataclass(frozen=True)
class Stream:
    """The selected grasps of one (object, hand), as batches read on demand."""

    info: ExportedObject
    hand: str
    batches: Iterator[list[Grasp]]
