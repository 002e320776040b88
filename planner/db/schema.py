"""The database schema and its migrations, in one place.

Tables (the README lists every column):

- ``meta``: key/value -- schema version, ranking rule (JSON), validation settings.
- ``objects``: one row per object name: source, scale, mesh hash, mass
  properties, friction, torque scale; (v12) its up; (v13) its geometry.
- ``units``: one row per unit of work (object, hand, settings hash, seed, chunk);
  a unit's grasps are written in the same transaction that marks it done, so
  an interrupted run leaves either all of a unit or none of it.
- ``grasps``: one row per evaluated grasp (a hand that closed on the object
  with contacts), with its pose, joints, contacts, quality, score and rank.
- ``validation`` (v2): the dynamic PyBullet trial of a grasp; (v3) why it
  ended as it did (``reason``).
- ``robust`` (v2): robust epsilon under pose and friction noise.
- ``grasps`` (v3) gains the analytic measures: ``resist_worst``,
  ``resist_mean`` (weight resistance [g]), ``open_margin``, ``close_margin``
  [m], ``push`` and ``feasibility`` (comma-separated reasons, '' when
  feasible); NULL for grasps stored before version 3 (not measured).
- ``grasps`` (v4) gains ``settled_epsilon``: the epsilon of the contacts the
  grasp settles into under a dynamic closing (hands with ``settle``); NULL
  when not measured.
- ``calibration`` (v5): the fitted p_hold model of a hand (``grasp calibrate``,
  :mod:`planner.calibration.model`; JSON) and where it came from (the label
  files, the sample, the held-out figures). A hand without a row uses the
  project's shipped model (``calibration/<hand>.toml``) if there is one.
- ``grasps`` (v5) gains ``p_hold``: the calibrated probability of holding,
  written by the store with the score (the hand's model on the stored
  measures); NULL where no model applies (and for grasps stored before,
  until the next write re-scores them: ``meta.p_hold_models``).
- ``grasps`` (v6) gains the grip measures (:mod:`planner.plan.grip`):
  ``pad_area``, ``pad_alignment``, ``opposition``, ``jaw_fill``,
  ``palm_gap``, ``com_lever``; NULL for grasps stored before (not measured);
  and ``table_plane``: the table top a grasp was planned on (``grasp
  generate --on-table``), object frame, JSON ``[nx, ny, nz, height]``; NULL
  for a grasp planned on the object alone (every grasp stored before).
- ``mujoco`` (v7): the MuJoCo trial of a grasp (``grasp validate --engine
  mujoco``, :mod:`planner.validation.mujoco_trial`: another engine and
  protocol than ``validation``'s), the same columns as ``validation``.
- ``grasps`` (v8) gains ``p_hold_trial``: p_hold updated by the verdict of
  the trial that tried the grasp (:mod:`planner.calibration.update`),
  written by the store with p_hold; NULL where no trial tried it or the
  hand's model has no update for that trial's engine.
- ``grasps`` (v9) gains the grip measures ``com_height`` and
  ``gravity_arm`` (:mod:`planner.plan.grip`: where the centre of mass sits
  about the grip, with the object's weight along -z); NULL for grasps
  stored before (not measured).
- ``grasps`` (v10) gains ``torque_per_mu`` (:mod:`planner.plan.measures`:
  the weight's torque about the grip axis over the friction coefficient);
  NULL for grasps stored before (not measured).
- ``grasps`` (v11) gains ``local_sdf`` (:mod:`planner.plan.local_sdf`: the
  object's signed distance at a grid fixed in the hand frame, a JSON list);
  NULL for grasps stored before and for hands without a grid.
- ``objects`` (v12) gains ``up`` (:mod:`planner.specs.up`: the axis of the
  object frame that is up as the object stands, ``+z``, ``+y``, ...);
  ``+z`` for objects stored before (the up every object had).
- ``objects`` (v13) gains ``geometry``: the elements of a URDF file the
  object is made of, ``collision`` or ``visual`` (``collision`` for objects
  stored before, what a user's URDF file was made of where it had any); its
  ``com`` and ``inertia`` are since the ones given (a sidecar's, a URDF's
  ``<inertial>``: :mod:`planner.specs.objects`), else the mesh's as before.
- ``grasps`` (v14) gains ``squeezed_force_closure``, ``squeezed_epsilon`` and
  ``squeeze_turn`` (:mod:`planner.plan.squeeze`: what a self-centring
  parallel jaw's squeeze ends in, beside the grasp as planned); NULL for
  grasps stored before and for hands that do not squeeze.
- ``grasps`` (v15) gains ``squeezed_from_turn`` [rad]: a squeeze's end
  stored as a grasp of its own (the sweep's, where the squeeze of a planned
  grasp that is not force closure ends force closure), how far it turned from
  its parent, which has the same unit and candidate; NULL for a grasp closed
  where planned (every grasp stored before). A grasp's key is since
  (unit, candidate, whether it is a squeeze's end): ``grasps_candidate``.
- ``file_labels`` (v16): the success label the file a grasp was imported
  from gives it (ACRONYM's ``flex/object_in_gripper``: FleX's, a user's
  outcomes) and where it was read; no row: none given.

No pickle: arrays are JSON text. A new database runs :data:`SCHEMA` (version
1) and then every migration; a newer schema is refused politely; an older one
is migrated after a backup copy is written next to the file.
"""

from __future__ import annotations

import logging
import os
import shutil
import sqlite3
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from planner.errors import DatabaseError

log = logging.getLogger(__name__)

SCHEMA_VERSION = 16

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

#: The ``grasps`` table's columns at v14 (:data:`SCHEMA`'s, then those migrations 2 .. 13 add), without its
#: ``UNIQUE (unit_id, candidate)``, and their names: what migration 14 copies.
_GRASPS_V14 = """
    id INTEGER PRIMARY KEY, unit_id INTEGER NOT NULL REFERENCES units(id) ON DELETE CASCADE,
    object TEXT NOT NULL, hand TEXT NOT NULL, preshape TEXT NOT NULL, candidate INTEGER NOT NULL,
    approach_point TEXT NOT NULL, approach_dir TEXT NOT NULL, roll REAL NOT NULL, standoff REAL NOT NULL,
    pose TEXT NOT NULL, open_joints TEXT NOT NULL, closed_joints TEXT NOT NULL, width REAL,
    contacts TEXT NOT NULL, n_contacts INTEGER NOT NULL, links_touching INTEGER NOT NULL,
    epsilon REAL NOT NULL, volume REAL NOT NULL, force_closure INTEGER NOT NULL,
    reachability REAL, manipulability REAL, seed INTEGER NOT NULL, score REAL NOT NULL, rank INTEGER,
    resist_worst REAL, resist_mean REAL, open_margin REAL, close_margin REAL, push REAL, feasibility TEXT,
    settled_epsilon REAL, p_hold REAL, pad_area REAL, pad_alignment REAL, opposition REAL, jaw_fill REAL,
    palm_gap REAL, com_lever REAL, table_plane TEXT, p_hold_trial REAL, com_height REAL, gravity_arm REAL,
    torque_per_mu REAL, local_sdf TEXT, squeezed_force_closure INTEGER, squeezed_epsilon REAL, squeeze_turn REAL"""
_COLUMNS_V14 = ", ".join(c.split()[0] for c in _GRASPS_V14.split(","))

#: from version -> SQL bringing it to version + 1.
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
    # v3: why a shake trial ended as it did (``held``, ``slipped``,
    # ``squeezed_out``, ``no_contact``, ``no_clearance``, ``start_overlap``;
    # '' for trials written before, which predate the reasons), and the
    # grasps' analytic measures (NULL for grasps stored before: not measured).
    2: """
ALTER TABLE validation ADD COLUMN reason TEXT NOT NULL DEFAULT '';
ALTER TABLE grasps ADD COLUMN resist_worst REAL;
ALTER TABLE grasps ADD COLUMN resist_mean REAL;
ALTER TABLE grasps ADD COLUMN open_margin REAL;
ALTER TABLE grasps ADD COLUMN close_margin REAL;
ALTER TABLE grasps ADD COLUMN push REAL;
ALTER TABLE grasps ADD COLUMN feasibility TEXT
""",
    # v4: the settled epsilon (issue 15, third round; NULL: not measured).
    3: """
ALTER TABLE grasps ADD COLUMN settled_epsilon REAL
""",
    # v5: fitted p_hold models, one per hand, and each grasp's p_hold (issue 26; NULL: no model).
    4: """
CREATE TABLE IF NOT EXISTS calibration (
    hand TEXT PRIMARY KEY, model TEXT NOT NULL, source TEXT NOT NULL, created_at TEXT NOT NULL
);
ALTER TABLE grasps ADD COLUMN p_hold REAL
""",
    # v6: the grip measures (issue 26, planner.plan.grip; NULL: not measured, grasps stored before) and the
    # table a grasp was planned on (issue 25; NULL: the object alone).
    5: """
ALTER TABLE grasps ADD COLUMN pad_area REAL;
ALTER TABLE grasps ADD COLUMN pad_alignment REAL;
ALTER TABLE grasps ADD COLUMN opposition REAL;
ALTER TABLE grasps ADD COLUMN jaw_fill REAL;
ALTER TABLE grasps ADD COLUMN palm_gap REAL;
ALTER TABLE grasps ADD COLUMN com_lever REAL;
ALTER TABLE grasps ADD COLUMN table_plane TEXT
""",
    # v7: the MuJoCo trial, a second dynamic protocol stored apart from PyBullet's (issue 26 item 6).
    6: """
CREATE TABLE IF NOT EXISTS mujoco (
    grasp_id INTEGER PRIMARY KEY REFERENCES grasps(id) ON DELETE CASCADE,
    success INTEGER NOT NULL, fingers_in_contact INTEGER NOT NULL,
    closing_linear REAL NOT NULL, closing_angular REAL NOT NULL,
    shaking_linear REAL NOT NULL, shaking_angular REAL NOT NULL,
    reason TEXT NOT NULL DEFAULT '', seed INTEGER NOT NULL, settings TEXT NOT NULL
)
""",
    # v8: p_hold given the trial's verdict (issue 26; NULL: not tried, or no update for its engine).
    7: """
ALTER TABLE grasps ADD COLUMN p_hold_trial REAL
""",
    # v9: the grip measures about gravity (issue 26; NULL: not measured, grasps stored before).
    8: """
ALTER TABLE grasps ADD COLUMN com_height REAL;
ALTER TABLE grasps ADD COLUMN gravity_arm REAL
""",
    # v10: the weight's torque about the grip over the friction (issue 26; NULL: not measured, grasps stored before).
    9: """
ALTER TABLE grasps ADD COLUMN torque_per_mu REAL
""",
    # v11: the object around the grasp, read by p_hold's trees (issue 26; NULL: not measured).
    10: """
ALTER TABLE grasps ADD COLUMN local_sdf TEXT
""",
    # v12: the object's up (an axis of its frame; '+z' for objects stored before, the up every object had).
    11: """
ALTER TABLE objects ADD COLUMN up TEXT NOT NULL DEFAULT '+z'
""",
    # v13: a URDF file's elements the object is made of ('collision' for objects stored before: a user's URDF
    # file could not be planned on its visual ones while it had collision ones).
    12: """
ALTER TABLE objects ADD COLUMN geometry TEXT NOT NULL DEFAULT 'collision'
""",
    # v14: what a parallel jaw's squeeze ends in, beside the planned grasp (issue 26; NULL: not squeezed).
    13: """
ALTER TABLE grasps ADD COLUMN squeezed_force_closure INTEGER;
ALTER TABLE grasps ADD COLUMN squeezed_epsilon REAL;
ALTER TABLE grasps ADD COLUMN squeeze_turn REAL
""",
    # v15: a squeeze's end stored as a grasp of its own beside its parent, the same unit and candidate (issue 26;
    # NULL: closed where planned, every grasp stored before). (unit, candidate) no longer names one grasp: the
    # table is built again (SQLite cannot drop a constraint) with ids kept (the trials' rows point at them),
    # its key now (unit, candidate, whether it is a squeeze's end). Run with foreign keys off (:func:`migrate`):
    # dropping the old table would delete every trial's row.
    14: f"""
CREATE TABLE grasps_v15 ({_GRASPS_V14}, squeezed_from_turn REAL);
INSERT INTO grasps_v15 ({_COLUMNS_V14}) SELECT {_COLUMNS_V14} FROM grasps;
DROP TABLE grasps;
ALTER TABLE grasps_v15 RENAME TO grasps;
CREATE INDEX IF NOT EXISTS grasps_rank ON grasps (object, hand, rank);
CREATE UNIQUE INDEX IF NOT EXISTS grasps_candidate ON grasps (unit_id, candidate, squeezed_from_turn IS NOT NULL)
""",
    # v16: an imported file's own success labels, kept beside this project's measures (ACRONYM's FleX labels).
    15: """
CREATE TABLE IF NOT EXISTS file_labels (
    grasp_id INTEGER PRIMARY KEY REFERENCES grasps(id) ON DELETE CASCADE,
    success INTEGER NOT NULL, source TEXT NOT NULL, seed INTEGER NOT NULL, settings TEXT NOT NULL
)
""",
}

#: Stand-ins for the version-2 tables when a version-1 file is read (opened
#: read-only, so it is not migrated): they have the columns and no rows.
EMPTY_V2_TABLES = {
    "validation": "(SELECT NULL AS grasp_id, NULL AS success, NULL AS fingers_in_contact, NULL AS closing_linear,"
                  " NULL AS closing_angular, NULL AS shaking_linear, NULL AS shaking_angular, NULL AS reason WHERE 0)",
    "robust": "(SELECT NULL AS grasp_id, NULL AS mean, NULL AS quantile, NULL AS samples WHERE 0)",
}
#: Stand-in for the version-7 ``mujoco`` table when an older file is read read-only.
EMPTY_V7_TABLES = {
    "mujoco": "(SELECT NULL AS grasp_id, NULL AS success, NULL AS fingers_in_contact, NULL AS closing_linear,"
              " NULL AS closing_angular, NULL AS shaking_linear, NULL AS shaking_angular, NULL AS reason WHERE 0)",
}
#: Stand-in for the version-16 ``file_labels`` table when an older file is read read-only.
EMPTY_V16_TABLES = {"file_labels": "(SELECT NULL AS grasp_id, NULL AS success, NULL AS source WHERE 0)"}
#: Every stand-in, by the table it stands in for.
EMPTY_TABLES = {**EMPTY_V2_TABLES, **EMPTY_V7_TABLES, **EMPTY_V16_TABLES}
#: A version-2 ``validation`` table read read-only (not migrated): its rows, reason unknown.
V2_VALIDATION = "(SELECT *, '' AS reason FROM validation)"


def schema_version(conn: sqlite3.Connection, path: Path) -> int:
    """The file's schema version; 0 for an empty file; a foreign database is refused, and so is one that lacks
    a column of its version (:func:`check_columns`)."""
    has_meta = conn.execute("SELECT name FROM sqlite_master WHERE type = 'table' AND name = 'meta'").fetchone()
    if not has_meta:
        tables = conn.execute("SELECT COUNT(*) AS n FROM sqlite_master WHERE type = 'table'").fetchone()["n"]
        if tables:
            raise DatabaseError(f"{path}: an SQLite file, but not a grasp database; pick another --db path")
        return 0
    row = conn.execute("SELECT value FROM meta WHERE key = 'schema_version'").fetchone()
    if row is None:
        return 0
    try:
        version = int(row["value"])
    except (TypeError, ValueError):
        raise DatabaseError(f"{path}: its schema version {row['value']!r} is not a number: not a grasp database "
                            "this planner wrote; pick another --db path") from None
    if 0 < version <= SCHEMA_VERSION:  # a newer one is refused as newer by its reader
        check_columns(conn, path, version)
    return version


def check_columns(conn: sqlite3.Connection, path: Path, version: int) -> None:
    """Refuse a file at schema ``version`` whose tables lack a column that version has (an ``ALTER TABLE ...
    DROP COLUMN``, a file edited or damaged): read, it failed on its first grasp as an internal error (a
    KeyError, a TypeError in a print). A table the file lacks is left to the readers (older files have none)."""
    from planner.record import fields

    tables = table_names(conn)
    missing = [f"{name}.{column}" for name in fields.TABLES if name in tables
               for column in sorted({f.column for f in fields.table(name) if f.version <= version}
                                    - column_names(conn, name))]
    if missing:
        raise DatabaseError(f"{path}: damaged: it lacks column{'s' * (len(missing) > 1)} {', '.join(missing)} of "
                            f"its schema v{version} (dropped, or edited by another program); restore it from a "
                            "backup, or build it again with `grasp generate`")


def table_names(conn: sqlite3.Connection) -> set[str]:
    return {r["name"] for r in conn.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}


def column_names(conn: sqlite3.Connection, table: str) -> set[str]:
    return {r["name"] for r in conn.execute(f"PRAGMA table_info({table})")}


@contextmanager
def transaction(conn: sqlite3.Connection, path: Path) -> Iterator[sqlite3.Connection]:
    """One atomic write; ``BEGIN IMMEDIATE`` takes the write lock up front.
    SQLite errors become one :class:`DatabaseError` saying nothing changed."""
    try:
        conn.execute("BEGIN IMMEDIATE")
    except sqlite3.OperationalError as exc:
        raise DatabaseError(f"{path}: database is locked by another writer ({exc})") from exc
    try:
        yield conn
        conn.execute("COMMIT")
    except BaseException as exc:
        if conn.in_transaction:
            conn.execute("ROLLBACK")
        if isinstance(exc, sqlite3.Error):
            raise DatabaseError(f"{path}: write failed, nothing was changed ({exc}); "
                                "is the file read-only or the disk full?") from exc
        raise


def migrate(conn: sqlite3.Connection, path: Path, version: int) -> None:
    """Bring a version-``version`` file (0: empty) to :data:`SCHEMA_VERSION`
    in one transaction, after a backup copy of an existing database. The copy opens and closes the file, and
    closing any descriptor of it drops the process's POSIX locks on it, SQLite's too: ``conn`` is to be closed
    after (:func:`~planner.db.store.open_db` opens the file again), or a reader's close in another process
    takes the file for the last connection's and deletes the -wal and -shm under the running writer."""
    if version > 0 and path.exists():
        backup = path.with_name(f"{path.name}.v{version}.{int(time.time())}.bak")
        conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
        partial = backup.with_name(f".{backup.name}.tmp")
        try:  # under its own name only when whole: a full disk left a damaged copy under the backup's name
            shutil.copy2(path, partial)
            os.replace(partial, backup)
        except OSError as exc:
            partial.unlink(missing_ok=True)
            raise DatabaseError(f"{path}: the backup copy before migrating schema v{version} -> v{SCHEMA_VERSION} "
                                f"could not be written ({exc.strerror or exc}): the database was not changed; free "
                                "disk space and run the command again") from exc
        log.warning("%s: migrating schema v%d -> v%d; backup at %s", path, version, SCHEMA_VERSION, backup)
    scripts = ([SCHEMA] if version == 0 else []) + [MIGRATIONS[v] for v in range(max(version, 1), SCHEMA_VERSION)]
    conn.execute("PRAGMA foreign_keys = OFF")  # a table built again (v15) drops the old: no cascade to its trials
    with transaction(conn, path):
        for script in scripts:
            # not executescript(): it would COMMIT the open transaction first
            for statement in filter(str.strip, script.split(";")):
                conn.execute(statement)
        conn.execute("INSERT INTO meta (key, value) VALUES ('schema_version', ?)"
                     " ON CONFLICT(key) DO UPDATE SET value = excluded.value", (str(SCHEMA_VERSION),))
