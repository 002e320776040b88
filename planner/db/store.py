"""The grasp database: SQLite (WAL), a versioned schema, one writer.

Tables (see the README for every column):

- ``meta``: key/value -- schema version, ranking rule (JSON).
- ``objects``: one row per object name: source, scale, mesh hash, mass
  properties, friction, torque scale.
- ``units``: one row per unit of work (object, hand, settings hash, seed, chunk);
  a unit's grasps are written in the same transaction that marks it done, so
  an interrupted run leaves either all of a unit or none of it.
- ``grasps``: one row per evaluated grasp (a hand that closed on the object
  with contacts), with its pose, joints, contacts, quality, score and rank.
- ``validation`` (v2): the dynamic PyBullet trial of a grasp (success, object
  motion during closing and shaking, settings).
- ``robust`` (v2): robust epsilon under pose and friction noise.

No pickle: arrays are JSON text. A newer schema refuses politely; an older one
is migrated after a backup copy is written next to the file.
"""

from __future__ import annotations

import json
import logging
import shutil
import sqlite3
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from planner.errors import DatabaseError

log = logging.getLogger(__name__)

SCHEMA_VERSION = 2
BUSY_TIMEOUT_S = 60.0

SCHEMA = """
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS objects (
    name TEXT PRIMARY KEY, source TEXT NOT NULL, scale REAL NOT NULL, mesh_sha256 TEXT NOT NULL,
    mass REAL NOT NULL, friction REAL NOT NULL, density REAL NOT NULL, volume REAL NOT NULL,
    com TEXT NOT NULL, inertia TEXT NOT NULL, torque_scale REAL NOT NULL, extents TEXT NOT NULL
);
CREATE TABLE IF NOT EXISTS units (
    id INTEGER PRIMARY KEY, object TEXT NOT NULL, hand TEXT NOT NULL, settings_hash TEXT NOT NULL,
    seed INTEGER NOT NULL, chunk INTEGER NOT NULL, settings TEXT NOT NULL, status TEXT NOT NULL, error TEXT,
    candidates INTEGER NOT NULL DEFAULT 0, grasps INTEGER NOT NULL DEFAULT 0,
    force_closure INTEGER NOT NULL DEFAULT 0, rejected TEXT, seconds REAL, finished_at TEXT,
    UNIQUE (object, hand, settings_hash, seed, chunk)
);
CREATE TABLE IF NOT EXISTS grasps (
    id INTEGER PRIMARY KEY, unit_id INTEGER NOT NULL REFERENCES units(id) ON DELETE CASCADE,
    object TEXT NOT NULL, hand TEXT NOT NULL, preshape TEXT NOT NULL, candidate INTEGER NOT NULL,
    approach_point TEXT NOT NULL, approach_dir TEXT NOT NULL, roll REAL NOT NULL, standoff REAL NOT NULL,
    pose TEXT NOT NULL, open_joints TEXT NOT NULL, closed_joints TEXT NOT NULL, width REAL,
    contacts TEXT NOT NULL, n_contacts INTEGER NOT NULL, links_touching INTEGER NOT NULL,
    epsilon REAL NOT NULL, volume REAL NOT NULL, force_closure INTEGER NOT NULL,
    reachability REAL, manipulability REAL,
    seed INTEGER NOT NULL, score REAL NOT NULL, rank INTEGER,
    UNIQUE (unit_id, candidate)
);
CREATE INDEX IF NOT EXISTS grasps_rank ON grasps (object, hand, rank);
"""


@dataclass(frozen=True)
class GraspRow:
    """One grasp as stored (JSON columns already decoded)."""

    id: int
    object: str
    hand: str
    preshape: str
    candidate: int
    approach_point: list[float]
    approach_dir: list[float]
    roll: float
    standoff: float
    pose: list[list[float]]
    open_joints: dict[str, float]
    closed_joints: dict[str, float]
    width: float | None
    contacts: list[dict]
    epsilon: float
    volume: float
    force_closure: bool
    reachability: float | None
    manipulability: float | None
    seed: int
    score: float
    rank: int | None


class Database:
    """A grasp database file; open with :func:`open_db`."""

    def __init__(self, path: Path, conn: sqlite3.Connection) -> None:
        self.path = path
        self.conn = conn

    def close(self) -> None:
        self.conn.close()

    def __enter__(self) -> Database:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @contextmanager
    def transaction(self) -> Iterator[sqlite3.Connection]:
        """One atomic write; ``BEGIN IMMEDIATE`` takes the write lock up front."""
        try:
            self.conn.execute("BEGIN IMMEDIATE")
        except sqlite3.OperationalError as exc:
            raise DatabaseError(f"{self.path}: database is locked by another writer ({exc})") from exc
        try:
            yield self.conn
            self.conn.execute("COMMIT")
        except BaseException as exc:
            if self.conn.in_transaction:
                self.conn.execute("ROLLBACK")
            if isinstance(exc, sqlite3.Error):
                raise DatabaseError(f"{self.path}: write failed, nothing was changed ({exc}); "
                                    "is the file read-only or the disk full?") from exc
            raise

    # -- meta ---------------------------------------------------------------
    def meta(self, key: str) -> str | None:
        row = self.conn.execute("SELECT value FROM meta WHERE key = ?", (key,)).fetchone()
        return None if row is None else row[0]

    def set_meta(self, conn: sqlite3.Connection, key: str, value: str) -> None:
        conn.execute("INSERT INTO meta (key, value) VALUES (?, ?)"
                     " ON CONFLICT(key) DO UPDATE SET value = excluded.value",
                     (key, value))

    # -- units --------------------------------------------------------------
    def units_done(self, hand: str, settings_hash: str, seed: int) -> set[tuple[str, int]]:
        """(object, chunk) of every finished unit with these settings."""
        rows = self.conn.execute(
            "SELECT object, chunk FROM units WHERE hand = ? AND settings_hash = ? AND seed = ? AND status = 'done'",
            (hand, settings_hash, seed))
        return {(r[0], r[1]) for r in rows}

    def integrity_check(self) -> list[str]:
        try:
            rows = self.conn.execute("PRAGMA integrity_check").fetchall()
        except sqlite3.DatabaseError as exc:
            return [str(exc)]
        return [r[0] for r in rows if r[0] != "ok"]

    def count(self, where: str = "1", params: Sequence[object] = ()) -> int:
        return int(self.conn.execute(f"SELECT COUNT(*) FROM grasps WHERE {where}", params).fetchone()[0])

    def best(self, obj: str, hand: str, top: int, offset: int = 0) -> list[GraspRow]:
        rows = self.conn.execute(
            "SELECT * FROM grasps WHERE object = ? AND hand = ? AND rank IS NOT NULL ORDER BY rank LIMIT ? OFFSET ?",
            (obj, hand, top, offset)).fetchall()
        return [row_to_grasp(r) for r in rows]

    def objects_for(self, hand: str) -> list[str]:
        return [r[0] for r in self.conn.execute("SELECT DISTINCT object FROM grasps WHERE hand = ?", (hand,))]


def row_to_grasp(r: sqlite3.Row) -> GraspRow:
    pose = json.loads(r["pose"])
    return GraspRow(
        id=r["id"], object=r["object"], hand=r["hand"], preshape=r["preshape"], candidate=r["candidate"],
        approach_point=json.loads(r["approach_point"]), approach_dir=json.loads(r["approach_dir"]),
        roll=r["roll"], standoff=r["standoff"], pose=[pose[i:i + 4] for i in range(0, 16, 4)],
        open_joints=json.loads(r["open_joints"]), closed_joints=json.loads(r["closed_joints"]), width=r["width"],
        contacts=json.loads(r["contacts"]), epsilon=r["epsilon"], volume=r["volume"],
        force_closure=bool(r["force_closure"]), reachability=r["reachability"], manipulability=r["manipulability"],
        seed=r["seed"], score=r["score"], rank=r["rank"],
    )


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
        version = _schema_version(conn, path)
    except sqlite3.DatabaseError as exc:
        raise DatabaseError(f"{path}: cannot open database: {exc}") from exc
    db = Database(path, conn)
    if version > SCHEMA_VERSION:
        conn.close()
        raise DatabaseError(f"{path}: schema version {version} is newer than this planner's ({SCHEMA_VERSION}); "
                            "upgrade the planner (pip install -U) to read it")
    if readonly:
        if version == 0:
            conn.close()
            raise DatabaseError(f"{path}: not a grasp database (no schema)")
        return db
    if version < SCHEMA_VERSION:
        _migrate(db, version)
    return db


def _schema_version(conn: sqlite3.Connection, path: Path) -> int:
    has_meta = conn.execute("SELECT name FROM sqlite_master WHERE type = 'table' AND name = 'meta'").fetchone()
    if not has_meta:
        tables = conn.execute("SELECT COUNT(*) FROM sqlite_master WHERE type = 'table'").fetchone()[0]
        if tables:
            raise DatabaseError(f"{path}: an SQLite file, but not a grasp database; pick another --db path")
        return 0
    row = conn.execute("SELECT value FROM meta WHERE key = 'schema_version'").fetchone()
    return int(row[0]) if row else 0


#: from version -> SQL bringing it to version + 1. A new database runs
#: ``SCHEMA`` (version 1) and then every migration.
MIGRATIONS: dict[int, str] = {
    1: """
CREATE TABLE IF NOT EXISTS validation (
    grasp_id INTEGER PRIMARY KEY REFERENCES grasps(id) ON DELETE CASCADE,
    success INTEGER NOT NULL, fingers_in_contact INTEGER NOT NULL,
    closing_linear REAL NOT NULL, closing_angular REAL NOT NULL,
    shaking_linear REAL NOT NULL, shaking_angular REAL NOT NULL,
    seed INTEGER NOT NULL, settings TEXT NOT NULL
);
CREATE TABLE IF NOT EXISTS robust (
    grasp_id INTEGER PRIMARY KEY REFERENCES grasps(id) ON DELETE CASCADE,
    mean REAL NOT NULL, quantile REAL NOT NULL, samples INTEGER NOT NULL,
    seed INTEGER NOT NULL, settings TEXT NOT NULL
)
""",
}


def _migrate(db: Database, version: int) -> None:
    if version > 0 and db.path.exists():
        backup = db.path.with_name(f"{db.path.name}.v{version}.{int(time.time())}.bak")
        db.conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
        shutil.copy2(db.path, backup)
        log.warning("%s: migrating schema v%d -> v%d; backup at %s", db.path, version, SCHEMA_VERSION, backup)
    try:
        with db.transaction() as conn:
            scripts = ([SCHEMA] if version == 0 else []) + [MIGRATIONS[v] for v in range(max(version, 1),
                                                                                       SCHEMA_VERSION)]
            for script in scripts:
                # not executescript(): it would COMMIT the open transaction first
                for statement in filter(str.strip, script.split(";")):
                    conn.execute(statement)
            db.set_meta(conn, "schema_version", str(SCHEMA_VERSION))
    except sqlite3.OperationalError as exc:
        raise DatabaseError(f"{db.path}: cannot write the database ({exc}); is it read-only?") from exc
