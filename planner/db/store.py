"""The grasp database: SQLite (WAL), one writer, and every SQL statement of
the project (the schema's own statements live in :mod:`planner.db.schema`).

Grasps go in and come out as :class:`planner.record.grasp.Grasp` records; rows are
read by column name. Scores are never computed in SQL: the store reads the
measures, asks the hand's p_hold model (:meth:`Database.model`:
``grasp calibrate``'s stored one, else the shipped one) for ``p_hold`` and
the :class:`~planner.db.ranking.RankingRule` for the scores, writes both
(``grasps.p_hold``, ``grasps.score``) and re-ranks each (object, hand) in
the rule's order. Records read back carry the stored p_hold; a new model
(stored, or shipped with a new version: ``meta.p_hold_models``) re-makes
both for every grasp of its hand.
"""

from __future__ import annotations

import functools
import hashlib
import inspect
import json
import math
import sqlite3
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

from planner.calibration import features
from planner.calibration.model import LogisticModel, default_model
from planner.db.ranking import ORDER_BY, RankingRule, rank_order, rule_measures
from planner.db.schema import (
    EMPTY_V2_TABLES,
    EMPTY_V7_TABLES,
    SCHEMA_VERSION,
    V2_VALIDATION,
    column_names,
    migrate,
    schema_version,
    table_names,
    transaction,
)
from planner.errors import DatabaseError
from planner.record import fields
from planner.record.contacts import HandContacts
from planner.record.field import Field
from planner.record.grasp import FIELDS as GRASP_FIELDS
from planner.record.grasp import Grasp, Joints, RobustEpsilon, Trial

if TYPE_CHECKING:
    from planner.geometry.solid import PreparedObject

#: How long a connection waits for another one's write lock [s].
BUSY_TIMEOUT_S = 60.0
#: Decimals kept of stored vectors (poses, approach rays, centre of mass: 0.1 um)
#: and of the inertia tensor [kg m^2].
VECTOR_DIGITS = 7
INERTIA_DIGITS = 10

#: The declared columns (:mod:`planner.record.fields`) of the record's tables.
_GRASPS = fields.table("grasps")
_TRIAL, _MUJOCO, _ROBUST = fields.group("validation"), fields.group("mujoco"), fields.group("robust")
#: Columns an insert writes: all but those SQLite (``id``) or the ranking (``rank``) fill.
_GRASP_COLUMNS = tuple(f.column for f in _GRASPS if f.column not in ("id", "rank"))
_VALIDATION_COLUMNS = tuple(f.column for f in fields.table("validation"))
_MUJOCO_COLUMNS = tuple(f.column for f in fields.table("mujoco"))
_ROBUST_COLUMNS = tuple(f.column for f in fields.table("robust"))
_OBJECTS = fields.table("objects")
_TABLE_PLANE = fields.by_name("table_plane")
_OBJECT_COLUMNS = tuple(f.column for f in _OBJECTS)
_UNIT_COLUMNS = ("object", "hand", "settings_hash", "seed", "chunk", "settings", "status", "error", "candidates",
                 "grasps", "force_closure", "rejected", "seconds", "finished_at")

#: Table -> its alias in the grasps query.
_ALIAS = {"grasps": "g", "validation": "v", "mujoco": "mj", "robust": "r"}


def _aliased(group: tuple[Field, ...]) -> str:
    return ", ".join(f"{_ALIAS[f.table]}.{f.column} AS {_ALIAS[f.table]}_{f.column}" for f in group)


#: A grasp with its validation, MuJoCo trial and robust rows (``v_*``, ``mj_*``, ``r_*``).
_SELECT_GRASPS = f"""
SELECT g.*, {_aliased(_TRIAL)}, {_aliased(_MUJOCO)}, {_aliased(_ROBUST)}
FROM grasps g {{join}} {{validation}} v ON v.grasp_id = g.id LEFT JOIN {{mujoco}} mj ON mj.grasp_id = g.id
LEFT JOIN {{robust}} r ON r.grasp_id = g.id
"""
#: What the ranking rule reads, by the rule's names.
_RANKED = ", ".join(f"{_ALIAS[f.table]}.{f.column} AS {f.ranked}" for f in fields.ranked_fields())
#: The stored columns a p_hold model reads (:data:`planner.calibration.features.COLUMNS`), as ``m_<column>``.
_MODEL_INPUTS = ", ".join(f"g.{fields.by_name(name).column} AS m_{name}" for name in features.COLUMNS)
_MEASURES = f"""
SELECT g.id, g.object, g.hand, {_RANKED}{{inputs}}
FROM grasps g LEFT JOIN validation v ON v.grasp_id = g.id LEFT JOIN mujoco mj ON mj.grasp_id = g.id
LEFT JOIN robust r ON r.grasp_id = g.id
"""
_RERANK = f"""
WITH ranked AS (
    SELECT id, ROW_NUMBER() OVER (ORDER BY {ORDER_BY}) AS r FROM grasps WHERE object = ? AND hand = ?
)
UPDATE grasps SET rank = ranked.r FROM ranked WHERE grasps.id = ranked.id
"""


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


def p_hold_of(col: dict, models: dict[str, LogisticModel | None]) -> list[float | None]:
    """p_hold of stored grasps rows (columns ``col``: ``hand`` and the model
    inputs of :data:`_MODEL_INPUTS`, named ``m_<column>``) by each row's
    hand's model; None where the hand has none."""
    n = len(col["hand"])
    out: list[float | None] = [None] * n
    for hand in sorted(set(col["hand"])):
        model = models.get(hand)
        if model is None:
            continue
        rows = [i for i, h in enumerate(col["hand"]) if h == hand]
        sub = {k: [col["m_" + k][i] for i in rows] for k in features.COLUMNS}
        for i, p in zip(rows, model.predict(features.of_columns(sub)).tolist()):
            out[i] = p
    return out


def _insert(table: str, columns: Sequence[str], verb: str = "INSERT") -> str:
    return f"{verb} INTO {table} ({', '.join(columns)}) VALUES ({', '.join('?' * len(columns))})"


def _json(values: object) -> str:
    return json.dumps(values, separators=(",", ":"))


def _vector(a: np.ndarray, digits: int = VECTOR_DIGITS) -> str:
    return _json([round(float(v), digits) for v in np.ravel(a)])


def json_list(texts: Iterable[str]) -> list:
    """Decode many JSON texts with one parser call (several times faster)."""
    return json.loads("[" + ",".join(texts) + "]")


def _vectors(texts: Sequence[str], shape: tuple[int, ...]) -> np.ndarray:
    """(n, *shape) floats of n stored vectors (flat JSON lists of numbers), parsed
    in one call; the numbers are the shortest round-trip texts, so exact."""
    flat = np.fromstring(",".join(t[1:-1] for t in texts), sep=",")
    return flat.reshape(len(texts), *shape)


def write_failed(path: Path, exc: sqlite3.Error, kept: int | None) -> str:
    """The one line for a write SQLite refused: why, what is kept, what to do.
    SQLite rolls the failed transaction back, so every commit before it stays."""
    name, text = getattr(exc, "sqlite_errorname", ""), str(exc)  # the name: Python >= 3.11
    if name.startswith("SQLITE_READONLY") or "readonly" in text:
        cause, fix = "the database is read-only", "make it writable"
    elif name == "SQLITE_FULL" or name.startswith("SQLITE_IOERR") or "disk" in text:
        # a full disk is SQLITE_FULL; a file-size limit (EFBIG) is SQLITE_IOERR_WRITE
        cause, fix = "the disk is full or the file may not grow", "free disk space"
    elif name.startswith(("SQLITE_BUSY", "SQLITE_LOCKED")) or "locked" in text:
        cause, fix = "another connection holds the write lock", "stop the other writer"
    else:
        cause, fix = "the write failed", "check it with `grasp db check`"
    units = "" if kept is None else f" ({kept} finished units)"
    return (f"{path}: cannot write: {cause} ({text}); this write was not stored and everything committed before "
            f"is kept{units}; {fix} and run the same command again to resume")


@dataclass(frozen=True)
class ObjectRow:
    """An ``objects`` row: the stored object's file and physical properties.

    ``scale`` turns ``source`` (the mesh file) into metres; ``com`` (3,) [m]
    and ``inertia`` (3, 3) [kg m^2] about the COM are in the scaled mesh frame;
    ``mesh_sha256``: :func:`~planner.geometry.mesh.mesh_hash` of the checked mesh.
    """

    name: str
    source: str
    scale: float
    mass: float
    friction: float
    density: float
    volume: float
    com: np.ndarray
    inertia: np.ndarray
    mesh_sha256: str = ""


@dataclass(frozen=True)
class UnitRow:
    """One unit of work as the ``units`` table holds it."""

    object: str
    hand: str
    settings_hash: str
    settings: str  # JSON
    seed: int
    chunk: int
    error: str | None = None
    candidates: int = 0
    rejected: dict[str, int] = field(default_factory=dict)
    seconds: float = 0.0


@dataclass(frozen=True)
class Validated:
    """What physical validation found for one stored grasp, and how: the
    PyBullet ``trial``, the ``robust`` epsilon and the MuJoCo trial
    (``mujoco``), each None where not run (a row already stored stays)."""

    grasp_id: int
    trial: Trial | None
    robust: RobustEpsilon | None
    seed: int
    trial_settings: str  # JSON
    robust_settings: str  # JSON
    mujoco: Trial | None = None
    mujoco_settings: str = ""  # JSON


def read_failed(path: Path, exc: sqlite3.Error) -> str:
    """The one line for a read SQLite refused (a damaged file, an I/O error)."""
    return f"{path}: cannot read the database ({exc}); check it with `grasp db check --db {path}`"


F = TypeVar("F", bound=Callable[..., Any])


def _reads(method: F) -> F:
    """A read of the database: SQLite's errors come out as one
    :class:`DatabaseError` line (a generator's, while it is iterated)."""
    if inspect.isgeneratorfunction(method):
        @functools.wraps(method)
        def rows(self: Database, *args: Any, **kwargs: Any) -> Iterator[Any]:
            try:
                yield from method(self, *args, **kwargs)
            except sqlite3.Error as exc:
                raise DatabaseError(read_failed(self.path, exc)) from exc
        return rows  # type: ignore[return-value]

    @functools.wraps(method)
    def read(self: Database, *args: Any, **kwargs: Any) -> Any:
        try:
            return method(self, *args, **kwargs)
        except sqlite3.Error as exc:
            raise DatabaseError(read_failed(self.path, exc)) from exc
    return read  # type: ignore[return-value]


class Database:
    """A grasp database file; open with :func:`open_db`."""

    def __init__(self, path: Path, conn: sqlite3.Connection) -> None:
        self.path = path
        self._conn = conn

    def close(self) -> None:
        self._conn.close()

    def __enter__(self) -> Database:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @contextmanager
    def _transaction(self) -> Iterator[sqlite3.Connection]:
        """One atomic write (:func:`planner.db.schema.transaction`); a write
        that fails says in one line why, and that what was committed before
        it is kept."""
        try:
            with transaction(self._conn, self.path) as conn:
                yield conn
        except DatabaseError as exc:
            if not isinstance(exc.__cause__, sqlite3.Error):
                raise
            raise DatabaseError(write_failed(self.path, exc.__cause__, self._units_kept())) from exc.__cause__

    def _units_kept(self) -> int | None:
        try:
            return int(self._conn.execute("SELECT COUNT(*) FROM units WHERE status = 'done'").fetchone()[0])
        except sqlite3.Error:
            return None

    # -- meta ---------------------------------------------------------------
    @_reads
    def meta(self, key: str) -> str | None:
        row = self._conn.execute("SELECT value FROM meta WHERE key = ?", (key,)).fetchone()
        return None if row is None else row["value"]

    def set_meta(self, key: str, value: str) -> None:
        with self._transaction() as conn:
            self._set_meta(conn, key, value)

    @staticmethod
    def _set_meta(conn: sqlite3.Connection, key: str, value: str) -> None:
        conn.execute("INSERT INTO meta (key, value) VALUES (?, ?)"
                     " ON CONFLICT(key) DO UPDATE SET value = excluded.value", (key, value))

    def rule(self) -> RankingRule:
        """The stored ranking rule (the default one for a new database)."""
        return RankingRule.from_json(self.meta("ranking"))

    def integrity_check(self) -> list[str]:
        """``PRAGMA integrity_check`` problems (empty list: healthy)."""
        try:
            rows = self._conn.execute("PRAGMA integrity_check").fetchall()
        except sqlite3.DatabaseError as exc:
            return [str(exc)]
        return [r["integrity_check"] for r in rows if r["integrity_check"] != "ok"]

    # -- writing units ----------------------------------------------------------
    @_reads
    def units_done(self, hand: str, settings_hash: str, seed: int) -> set[tuple[str, int]]:
        """(object, chunk) of every finished unit with these settings."""
        rows = self._conn.execute(
            "SELECT object, chunk FROM units WHERE hand = ? AND settings_hash = ? AND seed = ? AND status = 'done'",
            (hand, settings_hash, seed))
        return {(r["object"], r["chunk"]) for r in rows}

    def write_unit(self, unit: UnitRow, obj: PreparedObject | None, grasps: Sequence[Grasp],
                   rule: RankingRule) -> int:
        """Store a finished (or failed) unit, its object and its grasps
        atomically, then re-rank the object's grasps; returns the unit's id."""
        key = (unit.object, unit.hand, unit.settings_hash, unit.seed, unit.chunk)
        status = "failed" if unit.error else "done"
        scores, p_hold = self._scores(grasps, unit.hand, rule)
        with self._transaction() as conn:
            conn.execute("DELETE FROM units WHERE object = ? AND hand = ? AND settings_hash = ? AND seed = ?"
                         " AND chunk = ?", key)
            unit_id = conn.execute(_insert("units", _UNIT_COLUMNS), (
                *key, unit.settings, status, unit.error, unit.candidates, len(grasps),
                sum(g.force_closure for g in grasps), _json(unit.rejected), unit.seconds,
                time.strftime("%Y-%m-%dT%H:%M:%S"))).lastrowid
            if obj is not None:
                conn.execute(_insert("objects", _OBJECT_COLUMNS, "INSERT OR REPLACE"), _object_row(unit.object, obj))
            conn.executemany(_insert("grasps", _GRASP_COLUMNS),
                             [_grasp_row(g, unit_id, score, p) for g, score, p in zip(grasps, scores.tolist(), p_hold)])
            conn.execute(_RERANK, (unit.object, unit.hand))
        return int(unit_id)  # type: ignore[arg-type]

    def _scores(self, grasps: Sequence[Grasp], hand: str, rule: RankingRule) -> tuple[np.ndarray, list]:
        """(n,) scores and the n p_hold values (None: no model) of grasps of
        ``hand`` as :meth:`write_unit` stores them."""
        measures = rule_measures(grasps)
        model = self.model(hand)
        p_hold: list = [None] * len(grasps)
        if model is not None and grasps:  # the hand's model, on the records' measures; the rule reads it
            measures["p_hold"] = model.predict(features.of_grasps(grasps))
            p_hold = measures["p_hold"].tolist()
        return rule.scores(measures), p_hold

    def scored(self, grasps: Sequence[Grasp], hand: str) -> list[Grasp]:
        """Grasps not stored (planned by a query) with the score and p_hold
        this database would give them (its rule, the hand's model), best
        first as it would rank them (:func:`planner.db.ranking.rank_order`;
        ties in the given order); ``rank`` stays None."""
        if not grasps:
            return []
        scores, p_hold = self._scores(grasps, hand, self.rule())
        out = [replace(g, score=float(s), p_hold=p) for g, s, p in zip(grasps, scores.tolist(), p_hold)]
        return [out[i] for i in rank_order(scores, np.array([g.force_closure for g in grasps], float))]

    # -- ranking ---------------------------------------------------------------
    def apply_rule(self, rule: RankingRule, force: bool = False) -> bool:
        """Store ``rule``; if it differs from the stored one, or a hand's p_hold
        model is not the one its scores were made with (a new shipped model),
        or ``force``, re-score and re-rank every grasp in one transaction."""
        models = self._models_key()
        if self.meta("ranking") == rule.to_json() and self.meta("p_hold_models") == models and not force:
            return False
        with self._transaction() as conn:
            self._set_meta(conn, "ranking", rule.to_json())
            self._set_meta(conn, "p_hold_models", models)
            self._rescore(conn, rule)
        return True

    def _models_key(self) -> str:
        """Which p_hold model scores each stored hand (JSON, hashes of the
        models): scores made with other models are re-made by the next write."""
        hands = sorted({h for _, h in self.pairs()})
        return json.dumps({h: None if (m := self.model(h)) is None else
                           hashlib.sha256(m.to_json().encode()).hexdigest()[:16] for h in hands}, sort_keys=True)

    def _rescore(self, conn: sqlite3.Connection, rule: RankingRule, pair: tuple[str, str] | None = None,
                 hand: str | None = None) -> None:
        """Scores from the rule (all grasps, one object and hand, or one hand)
        and ranks, inside the caller's transaction."""
        where, params = ("", ()) if pair is None else (" WHERE g.object = ? AND g.hand = ?", pair)
        if hand is not None:
            where, params = " WHERE g.hand = ?", (hand,)
        hands = [r["hand"] for r in conn.execute("SELECT DISTINCT g.hand FROM grasps g" + where, params)]
        models = self._models(hands)
        inputs = ", " + _MODEL_INPUTS if any(m is not None for m in models.values()) else ""
        rows = conn.execute(_MEASURES.format(inputs=inputs) + where, params).fetchall()
        if not rows:
            return
        col = dict(zip(rows[0].keys(), zip(*rows)))
        col["p_hold"] = p_hold_of(col, models)  # the model's, not the stored one: the model may be new
        scores = rule.scores({f.ranked: col[f.ranked] for f in fields.ranked_fields()})
        conn.executemany("UPDATE grasps SET score = ?, p_hold = ? WHERE id = ?",
                         zip(scores.tolist(), col["p_hold"], col["id"]))
        for o, h in sorted(set(zip(col["object"], col["hand"]))):
            conn.execute(_RERANK, (o, h))

    # -- calibration -------------------------------------------------------------
    @_reads
    def model(self, hand: str) -> LogisticModel | None:
        """The hand's p_hold model: the one stored by ``grasp calibrate``, else
        the project's shipped one, else None."""
        if "calibration" in table_names(self._conn):
            row = self._conn.execute("SELECT model FROM calibration WHERE hand = ?", (hand,)).fetchone()
            if row is not None:
                return LogisticModel.from_json(row["model"])
        return default_model(hand)

    @_reads
    def model_source(self, hand: str) -> str:
        """Where the hand's model came from: the stored source, ``shipped`` or ``none``."""
        if "calibration" in table_names(self._conn):
            row = self._conn.execute("SELECT source FROM calibration WHERE hand = ?", (hand,)).fetchone()
            if row is not None:
                return str(row["source"])
        return "shipped" if default_model(hand) is not None else "none"

    def _models(self, hands: Iterable[str]) -> dict[str, LogisticModel | None]:
        return {h: self.model(h) for h in sorted(set(hands))}

    def write_model(self, model: LogisticModel, source: str, rule: RankingRule) -> None:
        """Store ``model`` as its hand's p_hold model (replacing any), then
        re-score and re-rank that hand's grasps, in one transaction."""
        with self._transaction() as conn:
            conn.execute(_insert("calibration", ("hand", "model", "source", "created_at"), "INSERT OR REPLACE"),
                         (model.hand, model.to_json(), source, time.strftime("%Y-%m-%dT%H:%M:%S")))
            self._rescore(conn, rule, hand=model.hand)
        self.set_meta("p_hold_models", self._models_key())

    def write_validation(self, obj: str, hand: str, results: Sequence[Validated], rule: RankingRule) -> None:
        """Store trial (PyBullet, MuJoCo) and robust-epsilon results of grasps
        of one (object, hand), then re-score and re-rank it, in one transaction."""
        with self._transaction() as conn:
            for v in results:
                if v.trial is not None:
                    t = v.trial
                    conn.execute(_insert("validation", _VALIDATION_COLUMNS, "INSERT OR REPLACE"),
                                 (v.grasp_id, *_row(_TRIAL, t), v.seed, v.trial_settings))
                if v.mujoco is not None:
                    conn.execute(_insert("mujoco", _MUJOCO_COLUMNS, "INSERT OR REPLACE"),
                                 (v.grasp_id, *_row(_MUJOCO, v.mujoco), v.seed, v.mujoco_settings))
                if v.robust is not None:
                    r = v.robust
                    conn.execute(_insert("robust", _ROBUST_COLUMNS, "INSERT OR REPLACE"),
                                 (v.grasp_id, *_row(_ROBUST, r), v.seed, v.robust_settings))
            self._rescore(conn, rule, (obj, hand))

    # -- reading ----------------------------------------------------------------
    @contextmanager
    def snapshot(self) -> Iterator[None]:
        """Reads inside see one committed state however many statements they
        take (one read transaction; in WAL mode the writer goes on meanwhile),
        so rank batches read while ``generate`` commits neither skip nor repeat."""
        if self._conn.in_transaction:
            yield
            return
        self._conn.execute("BEGIN")
        try:
            yield
        finally:
            self._conn.execute("COMMIT")

    @_reads
    def pairs(self) -> list[tuple[str, str]]:
        """Every (object, hand) with grasps, sorted."""
        rows = self._conn.execute("SELECT DISTINCT object, hand FROM grasps ORDER BY object, hand")
        return [(r["object"], r["hand"]) for r in rows]

    @_reads
    def objects_for(self, hand: str) -> list[str]:
        return [r["object"] for r in self._conn.execute("SELECT DISTINCT object FROM grasps WHERE hand = ?", (hand,))]

    @_reads
    def object_row(self, name: str) -> ObjectRow | None:
        r = self._conn.execute("SELECT * FROM objects WHERE name = ?", (name,)).fetchone()
        if r is None:
            return None
        kept = set(ObjectRow.__dataclass_fields__)
        return ObjectRow(**{f.column: next(iter(_decoded(f, [r[f.column]]))) for f in _OBJECTS if f.column in kept})

    @_reads
    def grasp_ids(self, unit_id: int) -> dict[int, int]:
        """Candidate number -> grasp id of one unit's grasps."""
        rows = self._conn.execute("SELECT candidate, id FROM grasps WHERE unit_id = ?", (unit_id,))
        return {r["candidate"]: r["id"] for r in rows}

    @_reads
    def best(self, obj: str, hand: str, top: int, offset: int = 0, *, table_plane: np.ndarray | None = None,
             other_planes: bool = False) -> list[Grasp]:
        """The grasps of rank ``offset + 1`` .. ``offset + top``, in rank order.
        With ``table_plane`` (4,) (one of :meth:`table_planes`), the
        ``offset + 1``-th .. of those planned on that table plane only, or,
        with ``other_planes``, of all the others (on another plane or none)."""
        where, params = "", [obj, hand]
        if table_plane is not None:
            where = " AND (g.table_plane IS NULL OR g.table_plane != ?)" if other_planes else " AND g.table_plane = ?"
            params.append(_sql(_TABLE_PLANE, table_plane))
        cur = self._conn.execute(self._select("LEFT JOIN") + " WHERE g.object = ? AND g.hand = ? AND g.rank IS NOT NULL"
                                 f"{where} ORDER BY g.rank LIMIT ? OFFSET ?", (*params, top, offset))
        return _grasps(cur.fetchall())

    @_reads
    def table_planes(self, obj: str, hand: str) -> list[np.ndarray]:
        """Every table plane (4,) [nx, ny, nz, height] that grasps of (obj,
        hand) were planned on (``grasp generate --on-table``), sorted; none
        in a file older than schema version 6 read read-only."""
        if _TABLE_PLANE.column not in column_names(self._conn, "grasps"):
            return []
        rows = self._conn.execute("SELECT DISTINCT table_plane FROM grasps WHERE object = ? AND hand = ? AND "
                                  "table_plane IS NOT NULL ORDER BY table_plane", (obj, hand)).fetchall()
        return list(_vectors([r["table_plane"] for r in rows], _TABLE_PLANE.shape)) if rows else []

    @_reads
    def grasp_batches(self, obj: str, hand: str, *, min_epsilon: float | None = None, top: int | None = None,
                      size: int = 5000) -> Iterator[list[Grasp]]:
        """The grasps of (obj, hand) with epsilon >= ``min_epsilon`` and rank <=
        ``top``, in rank order, ``size`` at a time (memory stays one batch)."""
        where, params = "", [obj, hand]
        if min_epsilon is not None:
            where += " AND g.epsilon >= ?"
            params.append(min_epsilon)
        if top is not None:
            where += " AND g.rank <= ?"
            params.append(top)
        cur = self._conn.cursor()
        cur.execute(self._select("LEFT JOIN") + f" WHERE g.object = ? AND g.hand = ? {where} ORDER BY g.rank, g.id",
                    params)
        try:
            while rows := cur.fetchmany(size):
                yield _grasps(rows)
        finally:
            cur.close()

    @_reads
    def validated(self) -> list[Grasp]:
        """Every grasp with a dynamic trial (PyBullet's or MuJoCo's), by hand, object and rank."""
        return _grasps(self._conn.execute(self._select("LEFT JOIN") + " WHERE v.grasp_id IS NOT NULL OR "
                                          "mj.grasp_id IS NOT NULL ORDER BY g.hand, g.object, g.rank").fetchall())

    def _select(self, join: str) -> str:
        """The grasps query; an older file read read-only is not migrated: a
        version-1 file has no v2 tables, a file before version 7 no MuJoCo
        trials (empty stand-ins), a version-2 file's trials have no reason (empty)."""
        tables = table_names(self._conn)
        names = {t: t if t in tables else empty for t, empty in {**EMPTY_V2_TABLES, **EMPTY_V7_TABLES}.items()}
        if "validation" in tables and "reason" not in column_names(self._conn, "validation"):
            names["validation"] = V2_VALIDATION
        return _SELECT_GRASPS.format(join=join, **names)


def _grasps(rows: list[sqlite3.Row]) -> list[Grasp]:
    """Rows of :data:`_SELECT_GRASPS` as records: vectors decoded per batch,
    joints and contacts kept as stored until used."""
    if not rows:
        return []
    col = dict(zip(rows[0].keys(), zip(*rows)))
    n = len(rows)
    parts = {name: _parts(g.cls, fields.group(name), col, "" if g.table == "grasps" else f"{_ALIAS[g.table]}_", n)
             for name, g in fields.GROUPS.items()}
    own = {f.attr: f for f in _GRASPS if "." not in f.attr}
    values = zip(*(parts[name] if name in parts else _own(own[name], col, n) for name in GRASP_FIELDS))
    return list(map(Grasp.restored, values))


def _own(f: Field, col: dict, n: int) -> Iterable:
    """A column of the record's own field; contacts keep their text and
    counts; a column that may be NULL and that an older file read read-only
    lacks (``p_hold`` before v5) is None."""
    if f.kind == "contacts":
        return map(HandContacts.stored, col["contacts"], col["n_contacts"], col["links_touching"])
    if f.nullable and f.column not in col:
        return [None] * n
    return _decoded(f, col[f.column])


def _object_row(name: str, obj: PreparedObject) -> tuple:
    """The objects row of a prepared object (:data:`_OBJECT_COLUMNS`)."""
    given = {"name": name, "source": obj.source_file, "scale": obj.file_scale, "mesh_sha256": obj.mesh_hash,
             "extents": obj.mesh.extents}
    return tuple(_sql(f, given[f.column] if f.column in given else getattr(obj, f.column)) for f in _OBJECTS)


def _grasp_row(g: Grasp, unit_id: int, score: float, p_hold: float | None) -> tuple:
    """The insert values of a record (:data:`_GRASP_COLUMNS`): what the store
    made of it (the unit, the rule's score, the hand's model's p_hold) and
    the record's own values."""
    given = {"unit_id": unit_id, "score": score, "p_hold": p_hold}
    return tuple(given[f.column] if f.column in given else _sql(f, get(g)) for f, get in _INSERTED)


_INSERTED = [(f, fields.getter(f)) for f in _GRASPS if f.column in _GRASP_COLUMNS]


def open_db(path: Path, *, create: bool = True, readonly: bool = False) -> Database:
    """Open (or create) a grasp database, checking what the file is first."""
    path = Path(path)
    exists = path.exists()
    if not exists and not create:
        raise DatabaseError(f"{path}: no such database; run `grasp generate ... --db {path}` first")
    if exists and path.is_dir():
        raise DatabaseError(f"{path}: is a folder, not a database file")
    if exists and path.stat().st_size > 0:
        with path.open("rb") as fh:
            if fh.read(16) != b"SQLite format 3\x00":
                raise DatabaseError(f"{path}: not an SQLite database; pick another --db path")
    if not exists and not path.parent.exists():
        raise DatabaseError(f"{path}: folder {path.parent} does not exist")
    try:
        uri = f"file:{path}?mode=ro" if readonly else f"file:{path}"
        conn = sqlite3.connect(uri, uri=True, timeout=BUSY_TIMEOUT_S, isolation_level=None)
        conn.row_factory = sqlite3.Row
        if not readonly:
            conn.execute("PRAGMA journal_mode = WAL")
            conn.execute("PRAGMA synchronous = NORMAL")
        conn.execute("PRAGMA foreign_keys = ON")
        version = schema_version(conn, path)
    except sqlite3.DatabaseError as exc:
        raise DatabaseError(f"{path}: cannot open database: {exc}") from exc
    if version > SCHEMA_VERSION:
        conn.close()
        raise DatabaseError(f"{path}: schema version {version} is newer than this planner's ({SCHEMA_VERSION}); "
                            "upgrade the planner (pip install -U) to read it")
    if readonly:
        if version == 0:
            conn.close()
            raise DatabaseError(f"{path}: not a grasp database (no schema)")
        return Database(path, conn)
    if version < SCHEMA_VERSION:
        migrate(conn, path, version)
    return Database(path, conn)
