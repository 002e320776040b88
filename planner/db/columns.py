"""The store's columns, from the fields declared once in
:mod:`planner.record.fields`: which columns each table has and which an
insert writes (:func:`_insert`), their aliases in the grasps query, and how
a record's value is stored in its column (:func:`_sql`, :func:`_row`) and
read back (:func:`_decoded`, :func:`_parts`; vectors as JSON text).
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Sequence

import numpy as np

from planner.record import fields
from planner.record.field import INERTIA_DIGITS, VECTOR_DIGITS, Field, stored_numbers
from planner.record.grasp import Joints

#: The declared columns (:mod:`planner.record.fields`) of the record's tables.
_GRASPS = fields.table("grasps")
_TRIAL, _MUJOCO, _ROBUST = fields.group("validation"), fields.group("mujoco"), fields.group("robust")
#: Columns an insert writes: all but those SQLite (``id``) or the ranking (``rank``) fill.
_GRASP_COLUMNS = tuple(f.column for f in _GRASPS if f.column not in ("id", "rank"))
_VALIDATION_COLUMNS = tuple(f.column for f in fields.table("validation"))
_MUJOCO_COLUMNS = tuple(f.column for f in fields.table("mujoco"))
_ROBUST_COLUMNS = tuple(f.column for f in fields.table("robust"))
_FILE_LABEL = fields.group("file_label")
_FILE_LABEL_COLUMNS = tuple(f.column for f in fields.table("file_labels"))
_OBJECTS = fields.table("objects")
_TABLE_PLANE = fields.by_name("table_plane")
_OBJECT_COLUMNS = tuple(f.column for f in _OBJECTS)
_UNIT_COLUMNS = ("object", "hand", "settings_hash", "seed", "chunk", "settings", "status", "error", "candidates",
                 "grasps", "force_closure", "rejected", "seconds", "finished_at")


#: Table -> its alias in the grasps query.
_ALIAS = {"grasps": "g", "validation": "v", "mujoco": "mj", "robust": "r", "file_labels": "fl"}


def _sql(f: Field, value: object) -> object:
    """A record's value as its column stores it."""
    if value is None:
        return None
    kind = f.kind
    if kind == "bool":
        return int(value)  # type: ignore[call-overload]
    if kind == "vector":
        return _vector(value, INERTIA_DIGITS if f.name == "object_inertia" else VECTOR_DIGITS)  # type: ignore[arg-type]
    if kind in ("joints", "contacts"):
        return value.json_text()  # type: ignore[attr-defined]
    if kind == "margin":
        return value if math.isfinite(value) else None  # type: ignore[arg-type]
    if kind == "reasons":
        return ",".join(value)  # type: ignore[arg-type]
    return value


def _row(group: tuple[Field, ...], record: object) -> tuple:
    """A record part's values (a Trial, RobustEpsilon, Measures), as stored, in the group's order."""
    return tuple(_sql(f, getattr(record, f.attr.partition(".")[2])) for f in group)


def _decoded(f: Field, column: Sequence) -> Iterable:
    """One column of rows as the record's values (a group's values: None stays None)."""
    kind = f.kind
    if kind == "bool":
        if "." not in f.attr and not f.nullable:  # always there: no NULL to keep
            return map(bool, column)
        return (None if v is None else bool(v) for v in column)
    if kind == "margin":
        return (math.inf if v is None else v for v in column)
    if kind == "reasons":
        return (None if v is None else tuple(r for r in v.split(",") if r) for v in column)
    if kind == "joints":
        return map(Joints.stored, column)
    if kind == "vector":
        if f.nullable:  # NULL: not there (a grasp planned without a table)
            column = list(column)
            present = [i for i, v in enumerate(column) if v is not None]
            out: list = [None] * len(column)
            for i, v in zip(present, _vectors([column[i] for i in present], f.shape) if present else []):
                out[i] = v
            return out
        return _vectors(column, f.shape)
    return column


def _parts(cls: type, group: tuple[Field, ...], col: dict, prefix: str, n: int) -> list:
    """The record parts (Trial, ...) of n rows (their columns named ``prefix`` +
    column); None where the group's first column is NULL (not validated, not
    measured, or a file older than the group). A group is every stored field
    of its type, in field order (:mod:`planner.record.fields`)."""
    none = [None] * n
    columns = [_decoded(f, col.get(prefix + f.column, none)) for f in group]
    present = col.get(prefix + group[0].column, none)
    return [None if first is None else cls(*row) for first, *row in zip(present, *columns)]


def _insert(table: str, columns: Sequence[str], verb: str = "INSERT") -> str:
    return f"{verb} INTO {table} ({', '.join(columns)}) VALUES ({', '.join('?' * len(columns))})"


def _json(values: object) -> str:
    return json.dumps(values, separators=(",", ":"))


def _vector(a: np.ndarray, digits: int = VECTOR_DIGITS) -> str:
    return _json(stored_numbers(a, digits))


def json_list(texts: Iterable[str]) -> list:
    """Decode many JSON texts with one parser call (several times faster)."""
    return json.loads("[" + ",".join(texts) + "]")


def _vectors(texts: Sequence[str], shape: tuple[int, ...]) -> np.ndarray:
    """(n, *shape) floats of n stored vectors (flat JSON lists of numbers), parsed
    in one call; the numbers are the shortest round-trip texts, so exact."""
    flat = np.fromstring(",".join(t[1:-1] for t in texts), sep=",")
    return flat.reshape(len(texts), *shape)
