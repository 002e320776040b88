"""Streaming reads of the grasp database for the exporters.

Rows are fetched per (object, hand) with ``fetchmany(BATCH_SIZE)`` and
decoded into column arrays one batch at a time, so no exporter ever holds
all grasps of a database in memory. Within a pair, rows come in rank order
(the ``grasps_rank`` index gives that order without a sort).
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from planner.datasets.batch import Batch, ObjectInfo, json_list
from planner.db.store import Database
from planner.errors import InputError

#: Rows per ``fetchmany``: about 10 MB of decoded columns.
BATCH_SIZE = 5000


@dataclass(frozen=True)
class Selection:
    """Which grasps to export (empty tuples: all)."""

    objects: tuple[str, ...] = ()
    hands: tuple[str, ...] = ()
    min_epsilon: float | None = None  # keep epsilon >= this
    top: int | None = None  # keep rank <= this per (object, hand)

    def __post_init__(self) -> None:
        if self.top is not None and self.top < 1:
            raise InputError(f"--top must be at least 1, got {self.top}")
        if self.min_epsilon is not None and not math.isfinite(self.min_epsilon):
            raise InputError(f"--min-epsilon must be a finite number, got {self.min_epsilon}")


_SQL = """
SELECT g.id, g.unit_id, g.preshape, g.candidate, g.seed, g.approach_point, g.approach_dir, g.roll, g.standoff,
       g.pose, g.open_joints, g.closed_joints, g.width, g.contacts, g.n_contacts, g.links_touching, g.epsilon,
       g.volume, g.force_closure, g.reachability, g.manipulability, g.score, g.rank,
       v.success, v.fingers_in_contact, v.closing_linear, v.closing_angular, v.shaking_linear, v.shaking_angular,
       r.mean, r.quantile, r.samples
FROM grasps g LEFT JOIN {validation} v ON v.grasp_id = g.id LEFT JOIN {robust} r ON r.grasp_id = g.id
WHERE g.object = ? AND g.hand = ? {where} ORDER BY g.rank, g.id
"""
#: Stand-ins for the schema v2 tables in a v1 database (opened read-only, so not migrated).
_EMPTY = {
    "validation": "(SELECT NULL AS grasp_id, NULL AS success, NULL AS fingers_in_contact, NULL AS closing_linear,"
                  " NULL AS closing_angular, NULL AS shaking_linear, NULL AS shaking_angular WHERE 0)",
    "robust": "(SELECT NULL AS grasp_id, NULL AS mean, NULL AS quantile, NULL AS samples WHERE 0)",
}
_INT = {"grasp_id", "unit_id", "candidate", "seed", "n_contacts", "links_touching", "force_closure", "rank",
        "sim_success", "sim_fingers", "robust_samples"}
_VEC = {"approach_point", "approach_dir", "pose"}
_TEXT = {"preshape", "open_joints", "closed_joints", "contacts"}


def pairs(db: Database, sel: Selection) -> list[tuple[str, str]]:
    """(object, hand) pairs to export; a named object or hand without grasps is an error."""
    found = [(r[0], r[1]) for r in db.conn.execute("SELECT DISTINCT object, hand FROM grasps ORDER BY object, hand")]
    for kind, wanted, index in (("object", sel.objects, 0), ("hand", sel.hands, 1)):
        known = sorted({p[index] for p in found})
        for name in wanted:
            if name not in known:
                raise InputError(f"{db.path}: no grasps of {kind} '{name}'; {kind}s with grasps: "
                                 f"{', '.join(known) or '(none)'}")
    return [p for p in found if (not sel.objects or p[0] in sel.objects) and (not sel.hands or p[1] in sel.hands)]


def object_info(db: Database, name: str) -> ObjectInfo:
    row = db.conn.execute("SELECT source, scale, mass, friction, density, volume, com, inertia FROM objects"
                          " WHERE name = ?", (name,)).fetchone()
    if row is None:
        nan = math.nan
        return ObjectInfo(name, "", nan, nan, nan, nan, nan, np.full(3, nan), np.full((3, 3), nan))
    return ObjectInfo(name, row[0], row[1], row[2], row[3], row[4], row[5],
                      np.array(json.loads(row[6]), float), np.array(json.loads(row[7]), float).reshape(3, 3))


def batches(db: Database, obj: str, hand: str, sel: Selection, size: int | None = None) -> Iterator[Batch]:
    """The selected grasps of (obj, hand) in rank order, ``size`` rows at a time."""
    where, params = "", [obj, hand]
    if sel.min_epsilon is not None:
        where += " AND g.epsilon >= ?"
        params.append(sel.min_epsilon)
    if sel.top is not None:
        where += " AND g.rank <= ?"
        params.append(sel.top)
    tables = {r[0] for r in db.conn.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
    joined = {t: t if t in tables else empty for t, empty in _EMPTY.items()}
    cur = db.conn.cursor()
    cur.execute(_SQL.format(where=where, **joined), params)
    try:
        while rows := cur.fetchmany(size or BATCH_SIZE):
            yield _decode(rows)
    finally:
        cur.close()


def _decode(rows: list[tuple]) -> Batch:
    columns = dict(zip(Batch.__dataclass_fields__, zip(*rows)))
    out: dict[str, object] = {}
    for name, values in columns.items():
        if name in _TEXT:
            out[name] = list(values)
        elif name in _VEC:
            out[name] = np.array(json_list(values), float)
        elif name in _INT:
            out[name] = np.array([-1 if v is None else v for v in values], np.int64)
        else:
            out[name] = np.array([math.nan if v is None else v for v in values], float)
    out["pose"] = out["pose"].reshape(-1, 4, 4)  # type: ignore[union-attr]
    return Batch(**out)  # type: ignore[arg-type]


def file_stem(obj: str, hand: str) -> str:
    """``{object}__{hand}`` with path separators in names replaced by ``__``."""
    return f"{obj}__{hand}".replace("/", "__").replace("\\", "__")

