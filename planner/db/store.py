"""The grasp database: SQLite (WAL), one writer, and every SQL statement of
the project (the schema's own statements live in :mod:`planner.db.schema`).

Grasps go in and come out as :class:`planner.grasp.Grasp` records; rows are
read by column name. Scores are never computed in SQL: the store reads the
measures, asks the :class:`~planner.db.ranking.RankingRule` for the scores,
writes them and re-ranks each (object, hand) in the rule's tie-break order.
"""

from __future__ import annotations

import hashlib
import json
import math
import sqlite3
import time
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from planner.calibration import features
from planner.calibration.model import LogisticModel, default_model
from planner.db.ranking import ORDER_BY, RankingRule, rule_measures
from planner.db.schema import (
    EMPTY_V2_TABLES,
    SCHEMA_VERSION,
    V2_VALIDATION,
    column_names,
    migrate,
    schema_version,
    table_names,
    transaction,
)
from planner.errors import DatabaseError
from planner.grasp import Grasp, Joints, RobustEpsilon, Trial
from planner.plan.contacts import HandContacts
from planner.plan.measures import Measures

if TYPE_CHECKING:
    from planner.geometry.solid import PreparedObject

#: How long a connection waits for another one's write lock [s].
BUSY_TIMEOUT_S = 60.0
#: Decimals kept of stored vectors (poses, approach rays, centre of mass: 0.1 um)
#: and of the inertia tensor [kg m^2].
VECTOR_DIGITS = 7
INERTIA_DIGITS = 10

#: The analytic measures (schema v3; v4 the settled epsilon), in the order of :func:`_measure_values`.
MEASURE_COLUMNS = ("resist_worst", "resist_mean", "open_margin", "close_margin", "push", "feasibility",
                   "settled_epsilon")
_GRASP_COLUMNS = ("unit_id", "object", "hand", "preshape", "candidate", "approach_point", "approach_dir", "roll",
                  "standoff", "pose", "open_joints", "closed_joints", "width", "contacts", "n_contacts",
                  "links_touching", "epsilon", "volume", "force_closure", "reachability", "manipulability", "seed",
                  "score", *MEASURE_COLUMNS)
_VALIDATION_COLUMNS = ("grasp_id", "success", "fingers_in_contact", "closing_linear", "closing_angular",
                       "shaking_linear", "shaking_angular", "reason", "seed", "settings")
_ROBUST_COLUMNS = ("grasp_id", "mean", "quantile", "samples", "seed", "settings")
_OBJECT_COLUMNS = ("name", "source", "scale", "mesh_sha256", "mass", "friction", "density", "volume", "com",
                   "inertia", "torque_scale", "extents")
_UNIT_COLUMNS = ("object", "hand", "settings_hash", "seed", "chunk", "settings", "status", "error", "candidates",
                 "grasps", "force_closure", "rejected", "seconds", "finished_at")

#: A grasp with its validation and robust rows (``v_*``, ``r_*``).
_SELECT_GRASPS = """
SELECT g.*, v.success AS v_success, v.fingers_in_contact AS v_fingers_in_contact,
       v.closing_linear AS v_closing_linear, v.closing_angular AS v_closing_angular,
       v.shaking_linear AS v_shaking_linear, v.shaking_angular AS v_shaking_angular, v.reason AS v_reason,
       r.mean AS r_mean, r.quantile AS r_quantile, r.samples AS r_samples
FROM grasps g {join} {validation} v ON v.grasp_id = g.id LEFT JOIN {robust} r ON r.grasp_id = g.id
"""
_MEASURES = """
SELECT g.id, g.object, g.hand, g.epsilon, g.force_closure, g.reachability, v.success, r.quantile,
       g.resist_worst, g.push, g.open_margin, g.close_margin, g.settled_epsilon,
       g.volume, g.width, g.n_contacts, g.links_touching, g.resist_mean, g.pose, g.approach_dir, g.contacts
FROM grasps g LEFT JOIN validation v ON v.grasp_id = g.id LEFT JOIN robust r ON r.grasp_id = g.id
"""
_RERANK = f"""
WITH ranked AS (
    SELECT id, ROW_NUMBER() OVER (ORDER BY {ORDER_BY}) AS r FROM grasps WHERE object = ? AND hand = ?
)
UPDATE grasps SET rank = ranked.r FROM ranked WHERE grasps.id = ranked.id
"""


def _measure_values(m: Measures | None) -> tuple:
    if m is None:
        return (None,) * len(MEASURE_COLUMNS)
    finite = [None if not math.isfinite(v) else v for v in (m.open_margin, m.close_margin)]
    return (m.resist_worst, m.resist_mean, *finite, m.push, ",".join(m.reasons), m.settled_epsilon)


def _measures(values: tuple) -> Measures | None:
    worst, mean, open_margin, close_margin, push, reasons, settled = values
    if worst is None:
        return None
    return Measures(worst, mean, math.inf if open_margin is None else open_margin,
                    math.inf if close_margin is None else close_margin, push,
                    tuple(r for r in reasons.split(",") if r), settled)


def rule_columns(col: dict) -> dict:
    """The measures the ranking rule reads, from columns of grasps rows."""
    none = [None] * len(col["id"])
    return {"epsilon": col["epsilon"], "force_closure": col["force_closure"], "reachability": col["reachability"],
            "success": col.get("success", none), "robust_quantile": col.get("quantile", none),
            "p_hold": col.get("p_hold", none),
            **{k: col.get(k, none) for k in ("resist_worst", "push", "open_margin", "close_margin",
                                             "settled_epsilon")}}


def p_hold_of(col: dict, models: dict[str, LogisticModel | None]) -> list[float | None]:
    """p_hold of stored grasps rows (columns ``col`` with ``hand`` and the
    measures of :data:`planner.calibration.features.MEASURES`) by each row's
    hand's model; None where the hand has none."""
    n = len(col["hand"])
    out: list[float | None] = [None] * n
    for hand in sorted(set(col["hand"])):
        model = models.get(hand)
        if model is None:
            continue
        rows = [i for i, h in enumerate(col["hand"]) if h == hand]
        sub = {k: [col[k][i] if k in col else None for i in rows]
               for k in (*features.MEASURES, "pose", "approach_dir", "contacts") if k != "depth"}
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
    """What physical validation found for one stored grasp, and how."""

    grasp_id: int
    trial: Trial | None
    robust: RobustEpsilon | None
    seed: int
    trial_settings: str  # JSON
    robust_settings: str  # JSON


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
        measures = rule_measures(grasps)
        model = self.model(unit.hand)
        if model is not None and grasps:
            measures["p_hold"] = model.predict(features.of_grasps(grasps))
        scores = rule.scores(measures)
        with self._transaction() as conn:
            conn.execute("DELETE FROM units WHERE object = ? AND hand = ? AND settings_hash = ? AND seed = ?"
                         " AND chunk = ?", key)
            unit_id = conn.execute(_insert("units", _UNIT_COLUMNS), (
                *key, unit.settings, status, unit.error, unit.candidates, len(grasps),
                sum(g.force_closure for g in grasps), _json(unit.rejected), unit.seconds,
                time.strftime("%Y-%m-%dT%H:%M:%S"))).lastrowid
            if obj is not None:
                conn.execute(_insert("objects", _OBJECT_COLUMNS, "INSERT OR REPLACE"), (
                    unit.object, obj.source_file, obj.file_scale, obj.mesh_hash, obj.mass, obj.friction, obj.density,
                    obj.volume, _vector(obj.com), _vector(obj.inertia, INERTIA_DIGITS), obj.torque_scale,
                    _vector(obj.mesh.extents)))
            conn.executemany(_insert("grasps", _GRASP_COLUMNS), [
                (unit_id, g.object, g.hand, g.preshape, g.candidate, _vector(g.approach_point),
                 _vector(g.approach_dir), g.roll, g.standoff, _vector(g.pose), g.open_joints.json_text(),
                 g.closed_joints.json_text(), g.width, g.contacts.json_text(), len(g.contacts), g.contacts.touching,
                 g.epsilon, g.volume, int(g.force_closure), g.reachability, g.manipulability, g.seed, score,
                 *_measure_values(g.measures))
                for g, score in zip(grasps, scores.tolist())])
            conn.execute(_RERANK, (unit.object, unit.hand))
        return int(unit_id)  # type: ignore[arg-type]

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
        rows = conn.execute(_MEASURES + where, params).fetchall()
        if not rows:
            return
        col = dict(zip(rows[0].keys(), zip(*rows)))
        col["p_hold"] = p_hold_of(col, self._models(col["hand"]))
        scores = rule.scores(rule_columns(col))
        conn.executemany("UPDATE grasps SET score = ? WHERE id = ?", zip(scores.tolist(), col["id"]))
        for o, h in sorted(set(zip(col["object"], col["hand"]))):
            conn.execute(_RERANK, (o, h))

    # -- calibration -------------------------------------------------------------
    def model(self, hand: str) -> LogisticModel | None:
        """The hand's p_hold model: the one stored by ``grasp calibrate``, else
        the project's shipped one, else None."""
        if "calibration" in table_names(self._conn):
            row = self._conn.execute("SELECT model FROM calibration WHERE hand = ?", (hand,)).fetchone()
            if row is not None:
                return LogisticModel.from_json(row["model"])
        return default_model(hand)

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
        """Store trial and robust-epsilon results of grasps of one (object,
        hand), then re-score and re-rank it, in one transaction."""
        with self._transaction() as conn:
            for v in results:
                if v.trial is not None:
                    t = v.trial
                    conn.execute(_insert("validation", _VALIDATION_COLUMNS, "INSERT OR REPLACE"), (
                        v.grasp_id, int(t.success), t.fingers_in_contact, t.closing_linear, t.closing_angular,
                        t.shaking_linear, t.shaking_angular, t.reason, v.seed, v.trial_settings))
                if v.robust is not None:
                    r = v.robust
                    conn.execute(_insert("robust", _ROBUST_COLUMNS, "INSERT OR REPLACE"),
                                 (v.grasp_id, r.mean, r.quantile, r.samples, v.seed, v.robust_settings))
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

    def pairs(self) -> list[tuple[str, str]]:
        """Every (object, hand) with grasps, sorted."""
        rows = self._conn.execute("SELECT DISTINCT object, hand FROM grasps ORDER BY object, hand")
        return [(r["object"], r["hand"]) for r in rows]

    def objects_for(self, hand: str) -> list[str]:
        return [r["object"] for r in self._conn.execute("SELECT DISTINCT object FROM grasps WHERE hand = ?", (hand,))]

    def object_row(self, name: str) -> ObjectRow | None:
        r = self._conn.execute("SELECT * FROM objects WHERE name = ?", (name,)).fetchone()
        if r is None:
            return None
        return ObjectRow(name, r["source"], r["scale"], r["mass"], r["friction"], r["density"], r["volume"],
                         np.array(json.loads(r["com"]), float), np.array(json.loads(r["inertia"]), float).reshape(3, 3),
                         r["mesh_sha256"])

    def grasp_ids(self, unit_id: int) -> dict[int, int]:
        """Candidate number -> grasp id of one unit's grasps."""
        rows = self._conn.execute("SELECT candidate, id FROM grasps WHERE unit_id = ?", (unit_id,))
        return {r["candidate"]: r["id"] for r in rows}

    def best(self, obj: str, hand: str, top: int, offset: int = 0) -> list[Grasp]:
        """The grasps of rank ``offset + 1`` .. ``offset + top``, in rank order."""
        cur = self._conn.execute(self._select("LEFT JOIN") + " WHERE g.object = ? AND g.hand = ? AND g.rank IS NOT NULL"
                                 " ORDER BY g.rank LIMIT ? OFFSET ?", (obj, hand, top, offset))
        return self._records(cur.fetchall())

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
                yield self._records(rows)
        finally:
            cur.close()

    def validated(self) -> list[Grasp]:
        """Every grasp with a shake trial, by hand, object and rank."""
        return self._records(self._conn.execute(self._select("JOIN") + " ORDER BY g.hand, g.object, g.rank")
                             .fetchall())

    def _records(self, rows: list[sqlite3.Row]) -> list[Grasp]:
        """Rows as records, with p_hold from each hand's model."""
        if not rows:
            return []
        hands = [r["hand"] for r in rows]
        return _grasps(rows, self._models(hands))

    def _select(self, join: str) -> str:
        """The grasps query; an older file read read-only is not migrated: a
        version-1 file has no v2 tables (empty stand-ins), a version-2 file's
        trials have no reason (empty)."""
        tables = table_names(self._conn)
        names = {t: t if t in tables else empty for t, empty in EMPTY_V2_TABLES.items()}
        if "validation" in tables and "reason" not in column_names(self._conn, "validation"):
            names["validation"] = V2_VALIDATION
        return _SELECT_GRASPS.format(join=join, **names)


def _grasps(rows: list[sqlite3.Row], models: dict[str, LogisticModel | None]) -> list[Grasp]:
    """Rows of :data:`_SELECT_GRASPS` as records: vectors decoded per batch,
    joints and contacts kept as stored until used; p_hold by ``models`` (hand -> model)."""
    if not rows:
        return []
    col = dict(zip(rows[0].keys(), zip(*rows)))
    p_hold = p_hold_of(col, models)
    trials = [None if ok is None else Trial(bool(ok), *rest) for ok, *rest in zip(
        col["v_success"], col["v_fingers_in_contact"], col["v_closing_linear"], col["v_closing_angular"],
        col["v_shaking_linear"], col["v_shaking_angular"], col["v_reason"])]
    robust = [None if mean is None else RobustEpsilon(mean, quantile, samples)
              for mean, quantile, samples in zip(col["r_mean"], col["r_quantile"], col["r_samples"])]
    values = zip(  # in the order of Grasp's fields
        col["object"], col["hand"], col["preshape"], col["candidate"], col["seed"],
        _vectors(col["approach_point"], (3,)), _vectors(col["approach_dir"], (3,)), col["roll"], col["standoff"],
        _vectors(col["pose"], (4, 4)), map(Joints.stored, col["open_joints"]),
        map(Joints.stored, col["closed_joints"]), col["width"],
        map(HandContacts.stored, col["contacts"], col["n_contacts"], col["links_touching"]), col["epsilon"],
        col["volume"], map(bool, col["force_closure"]), col["reachability"], col["manipulability"], col["id"],
        col["unit_id"], col["score"], col["rank"], trials, robust,
        map(_measures, zip(*(col.get(k, [None] * len(rows)) for k in MEASURE_COLUMNS))), p_hold)
    return list(map(Grasp.restored, values))


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
