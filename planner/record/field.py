"""The declaration of one stored field (:class:`Field`), and :func:`stored`,
which declares a record attribute as one.

A record type (:mod:`planner.record.grasp`, :mod:`planner.record.measures`)
declares each stored attribute with :func:`stored`; :mod:`planner.record.fields`
collects the declarations, adds the columns that are stored but not record
attributes, and is what the store, the ranking, the exports and the README
read.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

#: How a kind of value is stored and exported: (export dtype, SQL type, neutral value in an export).
#: ``margin`` is a length that is infinite when no finger touches (NULL in SQL);
#: ``reasons`` a tuple of names stored comma-separated ('' when empty).
KINDS: dict[str, tuple[str, str, object]] = {
    "real": ("float64", "REAL", math.nan),
    "margin": ("float64", "REAL", math.nan),
    "int": ("int64", "INTEGER", -1),
    "bool": ("int64", "INTEGER", -1),
    "text": ("string", "TEXT", ""),
    "reasons": ("string", "TEXT", ""),
    "vector": ("float64", "TEXT", math.nan),
    "joints": ("string", "TEXT", ""),
    "contacts": ("string", "TEXT", ""),
}

#: Decimals a ``vector`` keeps in the store (poses, approach rays, centre of mass: 0.1 um), and the inertia tensor
#: [kg m^2] (the objects' ``inertia``). Contacts keep theirs in :data:`planner.record.contacts.STORED_DIGITS`.
VECTOR_DIGITS = 7
INERTIA_DIGITS = 10
#: [m] How far a prepared object's centre of mass may lie from its stored row's and still be the stored one's.
COM_TOL = 10.0 ** (1 - VECTOR_DIGITS)
#: [kg m^2] How far a prepared object's inertia may lie from its stored row's (kept to INERTIA_DIGITS decimals),
#: relative to its largest entry or absolute, and still be the stored one.
INERTIA_RTOL, INERTIA_ATOL = 1e-6, 10.0 ** -INERTIA_DIGITS


def same_com(com: Any, stored_com: Any) -> bool:
    """Whether a centre of mass (3,) [m] is the stored one, to what the store keeps."""
    return float(np.linalg.norm(np.asarray(com, float) - np.asarray(stored_com, float))) <= COM_TOL


def same_inertia(inertia: Any, stored_inertia: Any) -> bool:
    """Whether an inertia (3, 3) or (9,) [kg m^2] is the stored one, to what the store keeps."""
    stored = np.asarray(stored_inertia, float).reshape(3, 3)
    turned = float(np.abs(np.asarray(inertia, float).reshape(3, 3) - stored).max())
    return turned <= max(INERTIA_RTOL * float(np.abs(stored).max()), INERTIA_ATOL)


def same_inertial(com: Any, inertia: Any, stored_com: Any, stored_inertia: Any) -> bool:
    """Whether a centre of mass (3,) [m] and inertia (3, 3) [kg m^2] are the stored ones, to what the store
    keeps."""
    return same_com(com, stored_com) and same_inertia(inertia, stored_inertia)


def stored_numbers(values: Any, digits: int = VECTOR_DIGITS) -> list[float]:
    """The numbers of an array as a ``vector`` column keeps them: flattened, each rounded to ``digits``
    decimals (written as their shortest round-trip text, so reading them back gives these very floats)."""
    return [round(float(v), digits) for v in np.ravel(values)]


@dataclass(frozen=True)
class Field:
    """One stored field.

    name: its flat name, as ``grasp_columns`` and the exports key it
        (``validation_success``, ``robust_mean``, ``push``, ``object_mass``).
    table, column: where the database keeps it (``grasps``, ``validation``,
        ``robust``, ``objects``) and under which column.
    attr: where the record holds it: ``epsilon``, ``measures.push``,
        ``validation.success``, ``robust.mean``; '' for a column the
        record does not hold (``n_contacts`` is ``len(contacts)``).
    kind: how it is stored and exported (see :data:`KINDS`); ``shape`` the
        shape of a ``vector`` ((3,), (4, 4)).
    dtype, sql: its export dtype and its SQL type (``NOT NULL`` where the
        database requires a value).
    unit: '' for none, else ``m``, ``rad``, ``g``, ``kg`` ...
    neutral: what an export holds when the value is absent (NaN, -1, '').
    version: the schema version the column appeared in.
    ranked: the name the ranking rule reads it by ('' if the rule does not).
    doc: one line.
    """

    name: str
    table: str
    column: str
    attr: str
    kind: str
    dtype: str
    sql: str
    unit: str
    neutral: object
    version: int
    ranked: str
    doc: str
    shape: tuple[int, ...] = ()

    @property
    def nullable(self) -> bool:
        """The database may hold NULL (not computed, not measured); a primary key may not."""
        return "NOT NULL" not in self.sql and "PRIMARY KEY" not in self.sql


def stored(kind: str, unit: str, version: int, doc: str, *, required: bool = True, key: bool = False,
           ranked: str = "", column: str = "", shape: tuple[int, ...] = (), default: Any = dataclasses.MISSING) -> Any:
    """A record attribute that is stored: a dataclass field whose metadata
    declares it (the record's table, name and attribute are added by
    :mod:`planner.record.fields`). ``required``: ``NOT NULL`` in SQL;
    ``key``: the table's primary key."""
    if kind not in KINDS:
        raise ValueError(f"stored field kind must be one of {', '.join(KINDS)}, got {kind!r}")
    meta = {"kind": kind, "unit": unit, "version": version, "doc": doc, "required": required, "key": key,
            "ranked": ranked, "column": column, "shape": shape}
    return dataclasses.field(default=default, metadata={"stored": meta})


def declared(table: str, column: str, attr: str, kind: str, unit: str, version: int, doc: str, *,
             name: str = "", required: bool = True, key: bool = False, ranked: str = "",
             shape: tuple[int, ...] = ()) -> Field:
    """A :class:`Field`, its dtype, SQL type and neutral value from its kind."""
    dtype, sql, neutral = KINDS[kind]
    sql += " PRIMARY KEY" if key else " NOT NULL" if required else ""
    return Field(name or column, table, column, attr, kind, dtype, sql, unit, neutral, version, ranked, doc, shape)
