"""The grasp database: SQLite (WAL), one writer. Every SQL statement of the
project lives in this package: the reads here, the writes in
:mod:`planner.db.writing` (:class:`Database` inherits them), the column
lists and inserts in :mod:`planner.db.columns`, the schema's own statements
in :mod:`planner.db.schema`.

Grasps go in and come out as :class:`planner.record.grasp.Grasp` records; rows are
read by column name. Scores are never computed in SQL: the store reads the
measures, asks the hand's p_hold model (:meth:`Database.model`:
``grasp calibrate``'s stored one, else the shipped one) for ``p_hold`` and
the :class:`~planner.db.ranking.RankingRule` for the scores, writes both
(``grasps.p_hold``, ``grasps.score``) and re-ranks each (object, hand) in
the rule's order. Records read back carry the stored p_hold; a new model
(stored, or shipped with a new version: ``meta.p_hold_models``) re-makes both for every grasp of its hand.
"""

from __future__ import annotations

import json
import logging
import os
import sqlite3
from collections.abc import Iterable, Iterator
from contextlib import closing, contextmanager
from pathlib import Path

import numpy as np

from planner.calibration.logistic import default_domain
from planner.calibration.model import LogisticModel, default_model
from planner.db.columns import (  # noqa: F401 - VECTOR_DIGITS, INERTIA_DIGITS, json_list re-exported
    _ALIAS,
    _FILE_LABEL,
    _GRASPS,
    _MUJOCO,
    _OBJECTS,
    _ROBUST,
    _TABLE_PLANE,
    _TRIAL,
    INERTIA_DIGITS,
    VECTOR_DIGITS,
    _decoded,
    _parts,
    _sql,
    _vectors,
    json_list,
)
from planner.db.failures import _reads, missing, read_failed, write_failed  # noqa: F401 - the failures re-exported
from planner.db.header import cannot_open, check_header, look, no_schema, uri
from planner.db.lock import writer_lock
from planner.db.ranking import END_KEPT, RankingRule, end_kept_sql, ranked_with_ends
from planner.db.rows import ObjectRow, UnitRow, Validated  # noqa: F401 - re-exported
from planner.db.schema import (
    EMPTY_TABLES,
    SCHEMA_VERSION,
    V2_VALIDATION,
    column_names,
    migrate,
    schema_version,
    table_names,
)
from planner.db.units import UnitReads
from planner.db.writing import Writing, p_hold_of  # noqa: F401 - p_hold_of re-exported
from planner.errors import DatabaseError
from planner.record import fields
from planner.record.contacts import HandContacts
from planner.record.field import Field
from planner.record.grasp import FIELDS as GRASP_FIELDS
from planner.record.grasp import Grasp

log = logging.getLogger(__name__)
#: Databases this process was told it reads as immutable (:func:`_frozen`).
_FROZEN_SAID: set[Path] = set()

#: How long a connection waits for another one's write lock [s].
BUSY_TIMEOUT_S = 60.0
SQL_MAX_INT = 2**63 - 1  # a count past SQLite's integers (--top 1e20) means "all", not an OverflowError


def _aliased(group: tuple[Field, ...]) -> str:
    return ", ".join(f"{_ALIAS[f.table]}.{f.column} AS {_ALIAS[f.table]}_{f.column}" for f in group)


#: A grasp with its validation, MuJoCo trial, robust and file label rows (``v_*``, ``mj_*``, ``r_*``, ``fl_*``) and
#: whether its squeeze's
#: end is stored beside it (``end_kept``: :func:`~planner.db.ranking.end_kept_sql`, 0 in a file before v15 and in one
#: ranked before such an end stood for its parent, :func:`~planner.db.ranking.ranked_with_ends`).
_SELECT_GRASPS = f"""
SELECT g.*, {_aliased(_TRIAL)}, {_aliased(_MUJOCO)}, {_aliased(_ROBUST)}, {_aliased(_FILE_LABEL)},
{{end_kept}} AS {END_KEPT}
FROM grasps g {{join}} {{validation}} v ON v.grasp_id = g.id LEFT JOIN {{mujoco}} mj ON mj.grasp_id = g.id
LEFT JOIN {{robust}} r ON r.grasp_id = g.id LEFT JOIN {{file_labels}} fl ON fl.grasp_id = g.id
"""


class Database(Writing, UnitReads):
    """A grasp database file; open with :func:`open_db`. Its writes are
    :class:`~planner.db.writing.Writing`'s, its reads of units :class:`~planner.db.units.UnitReads`'."""

    def __init__(self, path: Path, conn: sqlite3.Connection) -> None:
        self.path = path
        self._conn = conn

    def close(self) -> None:
        self._conn.close()

    def __enter__(self) -> Database:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- meta ---------------------------------------------------------------
    @_reads
    def meta(self, key: str) -> str | None:
        row = self._conn.execute("SELECT value FROM meta WHERE key = ?", (key,)).fetchone()
        return None if row is None else row["value"]

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

    # -- calibration -------------------------------------------------------------
    @_reads
    def model(self, hand: str) -> LogisticModel | None:
        """The hand's p_hold model: the one stored by ``grasp calibrate``, else the project's shipped one, else None."""
        if "calibration" in table_names(self._conn):
            row = self._conn.execute("SELECT model FROM calibration WHERE hand = ?", (hand,)).fetchone()
            if row is not None:
                return LogisticModel.from_json(row["model"])
        return default_model(hand)

    @_reads
    def model_domain(self, hand: str) -> dict[str, tuple[float, float]]:
        """The domain of the hand's model (:attr:`LogisticModel.domain`; {} if none), without building the model."""
        if "calibration" in table_names(self._conn):
            row = self._conn.execute("SELECT model FROM calibration WHERE hand = ?", (hand,)).fetchone()
            if row is not None:
                data = json.loads(row["model"]).get("domain", {})
                return {str(k): (float(v[0]), float(v[1])) for k, v in data.items()}
        return default_domain(hand)

    @_reads
    def model_source(self, hand: str) -> str:
        """Where the hand's model came from: the stored source, ``shipped`` or ``none``."""
        if "calibration" in table_names(self._conn):
            row = self._conn.execute("SELECT source FROM calibration WHERE hand = ?", (hand,)).fetchone()
            if row is not None:
                return str(row["source"])
        return "shipped" if default_model(hand) is not None else "none"

    @_reads
    def calibrated_hands(self) -> list[str]:
        """The hands with a model stored by ``grasp calibrate``, sorted."""
        has = "calibration" in table_names(self._conn)
        return [r["hand"] for r in self._conn.execute("SELECT hand FROM calibration ORDER BY hand")] if has else []

    def _models(self, hands: Iterable[str]) -> dict[str, LogisticModel | None]:
        return {h: self.model(h) for h in sorted(set(hands))}

    # -- reading ----------------------------------------------------------------
    @contextmanager
    def snapshot(self) -> Iterator[None]:
        """Reads inside see one committed state however many statements they take (one read transaction; in WAL
        mode the writer goes on meanwhile), so rank batches read while ``generate`` commits neither skip nor repeat."""
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
    def object_names(self) -> list[str]:
        """Every stored object, sorted (with or without grasps)."""
        return [r["name"] for r in self._conn.execute("SELECT name FROM objects ORDER BY name")]

    @_reads
    def objects_from(self, source: str) -> list[str]:
        """The stored objects whose ``source`` is this file (any name, any scale), sorted."""
        return [r["name"] for r in self._conn.execute("SELECT name FROM objects WHERE source = ? ORDER BY name",
                                                      (source,))]

    @_reads
    def object_row(self, name: str) -> ObjectRow | None:
        r = self._conn.execute("SELECT * FROM objects WHERE name = ?", (name,)).fetchone()
        if r is None:
            return None
        kept = set(ObjectRow.__dataclass_fields__) & set(r.keys())  # an older file read read-only: its columns
        return ObjectRow(**{f.column: next(iter(_decoded(f, [r[f.column]]))) for f in _OBJECTS if f.column in kept})

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
                                 f"{where} ORDER BY g.rank LIMIT ? OFFSET ?",
                                 (*params, min(top, SQL_MAX_INT), min(offset, SQL_MAX_INT)))
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
            params.append(min(top, SQL_MAX_INT))
        cur = self._conn.cursor()
        cur.execute(self._select("LEFT JOIN") + f" WHERE g.object = ? AND g.hand = ? {where} ORDER BY g.rank, g.id",
                    params)
        try:
            while rows := cur.fetchmany(size):
                yield _grasps(rows)
        finally:
            cur.close()

    @_reads
    def validated(self, *, file_labels: bool = False) -> list[Grasp]:
        """Every grasp a dynamic trial tried (PyBullet's, MuJoCo's; ``file_labels``: an imported file labelled)."""
        where = "fl.grasp_id IS NOT NULL" if file_labels else "v.grasp_id IS NOT NULL OR mj.grasp_id IS NOT NULL"
        return _grasps(self._conn.execute(f"{self._select('LEFT JOIN')} WHERE {where} ORDER BY g.hand, g.object, g.rank"
                                          ).fetchall())

    def _select(self, join: str) -> str:
        """The grasps query; an older file read read-only is not migrated: a
        version-1 file has no v2 tables, a file before version 7 no MuJoCo
        trials, one before 16 no file labels (empty stand-ins), a version-2 file's trials have no reason (empty)."""
        tables = table_names(self._conn)
        names = {t: t if t in tables else empty for t, empty in EMPTY_TABLES.items()}
        if "validation" in tables and "reason" not in column_names(self._conn, "validation"):
            names["validation"] = V2_VALIDATION
        ends = {"squeezed_from_turn", "squeezed_force_closure"} <= column_names(self._conn, "grasps") and \
            ranked_with_ends(self.meta("ranking"))  # an earlier version's ranks: as they rank (the next write re-ranks)
        return _SELECT_GRASPS.format(join=join, end_kept=end_kept_sql("g") if ends else "0", **names)


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
    parts[END_KEPT] = [bool(v) for v in col[END_KEPT]]  # not a column: the record's all the same
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


@contextmanager
def open_for_writing(path: Path, *, create: bool = True) -> Iterator[Database]:
    """The database under its writer lock (:func:`~planner.db.lock.writer_lock`), re-ranked where an earlier
    version ranked it (:meth:`~planner.db.writing.Writing.rank_anew`). A file that is not a grasp
    database is refused before the lock is taken and before anything is set in it: no lock file beside
    another application's SQLite file, and its journal mode as it was."""
    path = Path(path)
    if path.is_dir():  # "" is "." too
        raise DatabaseError(f"{path}: is a folder, not a database file")
    folder = path.resolve().parent  # SQLite's journal and the lock go beside the file itself (a symlink's target)
    if folder.is_dir() and not os.access(folder, os.W_OK):
        raise DatabaseError(f"{path}: its folder is read-only: a run writes beside the database (its lock and "
                            "SQLite's journal); nothing was changed: copy it to a writable folder")
    if not create and not path.exists():
        raise DatabaseError(missing(path))
    if not create and path.is_file() and path.stat().st_size == 0:  # validate made it a database (a stale lock's
        raise no_schema(path)  # owner on another host taken over too), and left a .lock beside it
    if path.is_file() and path.stat().st_nlink > 1:  # the lock is by name: a second name would let a second writer in
        raise DatabaseError(f"{path}: the file has {path.stat().st_nlink} names (hard links, e.g. a `cp -al` "
                            "snapshot): a writer through one would not see a writer through another, and a write "
                            "changes every name; nothing was changed: write to a copy (cp)")
    if path.is_file() and path.stat().st_size > 0:
        check_header(path)
        try:
            with closing(sqlite3.connect(look(path), uri=True, timeout=BUSY_TIMEOUT_S)) as conn:
                conn.row_factory = sqlite3.Row
                schema_version(conn, path)
        except sqlite3.DatabaseError as exc:
            raise cannot_open(path, exc) from exc
    with writer_lock(path), open_db(path, create=create) as db:
        db.rank_anew()
        yield db


def _frozen(path: Path) -> bool:
    """A database (its real file, through any symlink) in a folder this process cannot write in, nor the file
    itself (a read-only folder or filesystem: no writer through this path can make its journal there), with
    no write-ahead log to read: SQLite's read-only opening still makes a -shm file beside a WAL database, and
    fails there; read as immutable, it needs none. A writer through another mount of the same file is not
    seen (said when it is opened so: :func:`open_db`)."""
    real = path.resolve()
    wal = real.with_name(real.name + "-wal")
    return (real.is_file() and not os.access(real.parent, os.W_OK) and not os.access(real, os.W_OK)
            and not (wal.exists() and wal.stat().st_size > 0))


def open_db(path: Path, *, create: bool = True, readonly: bool = False) -> Database:
    """Open (or create) a grasp database, checking what the file is first."""
    path = Path(path)
    exists = path.exists()
    if not exists and not create:
        raise DatabaseError(missing(path))
    if exists and path.is_dir():
        raise DatabaseError(f"{path}: is a folder, not a database file")
    if exists and path.stat().st_size > 0:
        check_header(path)
    if not exists and not path.parent.exists():
        raise DatabaseError(f"{path}: folder {path.parent} does not exist")
    try:
        real = path.resolve()  # a reader of a writable file (a write bit too: root's access() ignores a chmod 444)
        tidy = readonly and all(os.access(p, os.W_OK) for p in (real, real.parent)) and real.stat().st_mode & 0o222 > 0
        target = uri(path, f"mode={'rw' if tidy else 'ro'}" if readonly else "")
        if readonly and _frozen(path):  # SQLite cannot make its -shm beside it: read it as the file that it is
            target = uri(path.resolve(), "mode=ro&immutable=1")
            if path not in _FROZEN_SAID:  # once: a command opens its database several times
                _FROZEN_SAID.add(path)
                log.warning("%s: in a read-only folder: read as it is now (a writer through another mount of it "
                            "would not be seen)", path)
        conn = sqlite3.connect(target, uri=True, timeout=BUSY_TIMEOUT_S, isolation_level=None)
        conn.row_factory = sqlite3.Row
        conn.execute(f"PRAGMA query_only = {int(tidy)}")  # unlike mode=ro, its close removes -wal/-shm (best left both)
        version = schema_version(conn, path)  # before anything is set: another application's file stays as it is
        if not readonly:
            conn.execute("PRAGMA journal_mode = WAL")
            conn.execute("PRAGMA synchronous = NORMAL")
        conn.execute("PRAGMA foreign_keys = ON")
    except sqlite3.DatabaseError as exc:
        if str(exc) == "file is not a database":
            raise cannot_open(path, exc) from exc
        if readonly and not os.access(path.resolve().parent, os.W_OK):
            raise DatabaseError(f"{path}: cannot read it in a read-only folder while its file may be written "
                                f"(SQLite needs a -shm file beside it; {exc}): copy it to a writable folder, or "
                                "make the file read-only too") from exc
        raise cannot_open(path, exc) from exc
    if version > SCHEMA_VERSION:
        conn.close()
        raise DatabaseError(f"{path}: schema version {version} is newer than this planner's ({SCHEMA_VERSION}); "
                            "upgrade the planner (pip install -U) to read it")
    if readonly and version == 0:
        raise no_schema(path, conn)
    if readonly or version == SCHEMA_VERSION:
        return Database(path, conn)
    migrate(conn, path, version)  # reopened: the backup's copy dropped this process's locks on the file (migrate)
    conn.close()
    return open_db(path, create=create)
