"""The schema: files that are not ours are refused untouched, newer ones
politely, older ones migrated after a backup."""

from __future__ import annotations

import shutil
import sqlite3
from dataclasses import replace
from pathlib import Path

import pytest
from helpers import FAST, grasp, one_line_error

from planner.db.schema import MIGRATIONS, SCHEMA, SCHEMA_VERSION
from planner.db.store import open_db
from planner.errors import DatabaseError


def rows(path: Path) -> list[tuple]:
    with sqlite3.connect(path) as conn:
        return conn.execute("SELECT * FROM grasps ORDER BY id").fetchall()


def test_not_sqlite_is_refused_and_untouched(tmp_path: Path) -> None:
    path = tmp_path / "notes.db"
    path.write_text("my precious notes")
    with pytest.raises(DatabaseError, match="not an SQLite database"):
        open_db(path)
    assert path.read_text() == "my precious notes"


def test_foreign_sqlite_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "other.db"
    with sqlite3.connect(path) as conn:
        conn.execute("CREATE TABLE t (x)")
    with pytest.raises(DatabaseError, match="not a grasp database"):
        open_db(path)


@pytest.mark.parametrize("command", [["generate", "box", "--hand", "panda", *FAST], ["validate"]])
def test_another_applications_sqlite_file_is_left_as_it_was(tmp_path: Path, command: list[str]) -> None:
    """Refused before anything is set in it (its journal mode) or made beside it (the writer's lock file)."""
    path = tmp_path / "other.db"
    with sqlite3.connect(path) as conn:
        conn.execute("CREATE TABLE t (x)")
    before = path.read_bytes()
    code, _, err = grasp(*command, "--db", str(path))
    one_line_error(code, err, 3, "an SQLite file, but not a grasp database")
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["other.db"]


def test_validate_on_a_missing_database_makes_no_lock_file(tmp_path: Path) -> None:
    code, _, err = grasp("validate", "--db", str(tmp_path / "none.db"))
    one_line_error(code, err, 3, "no such database")
    assert list(tmp_path.iterdir()) == []


def test_newer_schema_refuses_politely(tmp_path: Path) -> None:
    path = tmp_path / "new.db"
    open_db(path).close()
    with sqlite3.connect(path) as conn:
        conn.execute("UPDATE meta SET value = ? WHERE key = 'schema_version'", (str(SCHEMA_VERSION + 1),))
    with pytest.raises(DatabaseError, match="newer than this planner"):
        open_db(path)


def test_a_schema_version_that_is_no_number_is_refused_in_one_line(box_db: Path, tmp_path: Path) -> None:
    """A meta table whose schema_version is not an integer (another program's, or edited) was an internal error
    (ValueError, exit 1) in every command; now a DatabaseError (exit 3), the file untouched."""
    path = tmp_path / "odd.db"
    shutil.copy(box_db, path)
    with sqlite3.connect(path) as conn:
        conn.execute("UPDATE meta SET value = 'abc' WHERE key = 'schema_version'")
    before = path.read_bytes()
    for command in (["best", "box", "--hand", "panda"], ["generate", "box", "--hand", "panda", *FAST, "--quiet"]):
        code, _, err = grasp(*command, "--db", str(path))
        one_line_error(code, err, 3, "schema version 'abc' is not a number")
    assert path.read_bytes() == before


@pytest.mark.parametrize("column", ["resist_mean", "epsilon", "width"])
def test_a_dropped_column_is_refused_in_one_line_naming_the_file_and_the_column(box_db: Path, tmp_path: Path,
                                                                                column: str) -> None:
    """A grasps column dropped (``ALTER TABLE ... DROP COLUMN``: a damaged or hand-edited file) was an internal
    error when read (resist_mean: a TypeError in best's print; epsilon: a KeyError), or, where the column may be
    NULL (width), read as never measured; now a DatabaseError (exit 3) naming both, before any lock file."""
    path = tmp_path / "dropped.db"
    shutil.copy(box_db, path)
    with sqlite3.connect(path) as conn:
        conn.execute(f"ALTER TABLE grasps DROP COLUMN {column}")
    for command in (["best", "box", "--hand", "panda"], ["show", "box", "--hand", "panda", "--out", "x.png"],
                    ["export", "--format", "csv", "--out", str(tmp_path / "csv")],
                    ["report", "--out", str(tmp_path / "r.html")],
                    ["generate", "box", "--hand", "panda", *FAST, "--quiet"]):
        code, _, err = grasp(*command, "--db", str(path))
        one_line_error(code, err, 3, f"{path}: damaged: it lacks column grasps.{column} of its schema v")
    assert {p.name for p in tmp_path.iterdir()} <= {"dropped.db", "dropped.db-wal", "dropped.db-shm"}  # no lock


def test_not_sqlite_newer_schema_and_read_only(box_db: Path, tmp_path: Path) -> None:
    junk = tmp_path / "junk.db"
    junk.write_bytes(b"\x00not a database at all" * 100)
    code, _, err = grasp("generate", "box", "--hand", "panda", "--db", str(junk), *FAST, "--quiet")
    one_line_error(code, err, 3, "not an SQLite database")
    newer = tmp_path / "newer.db"
    shutil.copy(box_db, newer)
    with sqlite3.connect(newer) as conn:
        conn.execute("UPDATE meta SET value = ? WHERE key = 'schema_version'", (str(SCHEMA_VERSION + 5),))
    code, _, err = grasp("best", "box", "--hand", "panda", "--db", str(newer))
    one_line_error(code, err, 3, "newer than this planner")
    with open_db(box_db, create=False, readonly=True) as db:  # a read-only handle stands in for a read-only file
        with pytest.raises(DatabaseError, match="read-only"):
            db.set_meta("ranking", "{}")
    assert rows(box_db)


def test_older_schema_is_migrated_after_a_backup(tmp_path: Path) -> None:
    old = tmp_path / "old.db"
    with sqlite3.connect(old) as conn:
        for statement in filter(str.strip, SCHEMA.split(";")):
            conn.execute(statement)
        conn.execute("INSERT INTO meta VALUES ('schema_version', '1')")
        conn.execute("INSERT INTO objects VALUES ('o', 's', 1, 'h', 1, 0.5, 1, 1, '[]', '[]', 0.1, '[]')")
    with open_db(old) as db:
        assert db.meta("schema_version") == str(SCHEMA_VERSION)
    with sqlite3.connect(old) as conn:
        assert conn.execute("SELECT name FROM objects").fetchall() == [("o",)]
    backups = list(tmp_path.glob("old.db.v1.*.bak"))
    assert len(backups) == 1
    with sqlite3.connect(backups[0]) as conn:
        assert conn.execute("SELECT value FROM meta").fetchone()[0] == "1"


def version_2_file(path: Path) -> None:
    """A database as version 2 wrote it: one grasp with a shake trial (no reason)."""
    with sqlite3.connect(path) as conn:
        for statement in filter(str.strip, (SCHEMA + ";" + MIGRATIONS[1]).split(";")):
            conn.execute(statement)
        conn.execute("INSERT INTO meta VALUES ('schema_version', '2')")
        conn.execute("INSERT INTO units (id, object, hand, settings_hash, seed, chunk, settings, status)"
                     " VALUES (1, 'o', 'panda', 'h', 0, 0, '{}', 'done')")
        conn.execute("INSERT INTO grasps VALUES (1, 1, 'o', 'panda', 'wide', 0, '[0,0,0]', '[0,0,1]', 0, 0,"
                     " '[1,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1]', '{}', '{}', NULL, '[]', 0, 0, 0.1, 0.01, 1, NULL, NULL,"
                     " 0, 0.1, 1)")
        conn.execute("INSERT INTO validation VALUES (1, 1, 2, 0.001, 0.01, 0.002, 0.02, 0, '{}')")


def test_version_2_trials_read_back_with_an_unknown_reason(tmp_path: Path) -> None:
    old = tmp_path / "v2.db"
    version_2_file(old)
    with open_db(old, create=False, readonly=True) as db:  # read-only: not migrated
        (g,) = db.validated()
        assert db.meta("schema_version") == "2"
    assert g.validation.success and g.validation.reason == ""  # type: ignore[union-attr]
    with open_db(old) as db:  # migrated to the latest: the column exists, old rows keep ''
        assert db.meta("schema_version") == str(SCHEMA_VERSION)
        assert db.validated()[0].validation == g.validation
        assert db.validated()[0].measures is None  # v3 and v4 measures: not measured
    assert len(list(tmp_path.glob("v2.db.v2.*.bak"))) == 1



def test_the_readme_gives_the_schema_version() -> None:
    readme = (Path(__file__).parents[2] / "README.md").read_text(encoding="utf-8")
    assert f"Schema version {SCHEMA_VERSION};" in readme


def test_a_backup_that_cannot_be_written_leaves_neither_a_damaged_copy_nor_a_changed_file(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A full disk while the backup was copied left a damaged copy under the backup's own name (a helper's
    tmpfs: 3.2 of 5 MB, "malformed") and an internal error; now one line, no copy, the file as it was."""
    import errno

    from planner.db import schema

    old = tmp_path / "old.db"
    with sqlite3.connect(old) as conn:
        for statement in filter(str.strip, SCHEMA.split(";")):
            conn.execute(statement)
        conn.execute("INSERT INTO meta VALUES ('schema_version', '1')")
    conn.close()

    def copy_half_then_fail(src: Path, dst: Path) -> None:
        Path(dst).write_bytes(Path(src).read_bytes()[:1000])
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(schema.shutil, "copy2", copy_half_then_fail)
    with pytest.raises(DatabaseError, match=r"backup copy .* could not be written \(No space left on device\): the "
                                            "database was not changed"):
        open_db(old)
    with sqlite3.connect(old) as conn:
        assert conn.execute("SELECT value FROM meta WHERE key = 'schema_version'").fetchone()[0] == "1"
    conn.close()
    assert not [p.name for p in tmp_path.iterdir() if p.name.endswith((".bak", ".tmp"))]


def test_a_database_in_a_read_only_folder_is_read_and_writers_say_why_not(
        box_db: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture) -> None:
    """SQLite's read-only opening of a WAL database makes a -shm file beside it, and failed in a read-only
    folder ("unable to open database file" for best, show, export, db check); a writer said the same. Readers
    now read the file as immutable there, writers refuse in one line. (This process may write anywhere as
    root: the folder is reported read-only. Checked on a read-only tmpfs too: bench/RESULTS.md, 2026-12-06.)"""
    import os

    from planner.db import store

    folder = tmp_path / "ro"
    folder.mkdir()
    db = folder / "g.db"
    shutil.copy(box_db, db)
    real = os.access
    read_only = {folder.resolve(), db.resolve()}  # a read-only filesystem: neither may be written
    monkeypatch.setattr(store.os, "access",
                        lambda p, mode: False if mode == os.W_OK and Path(p).resolve() in read_only else real(p, mode))
    opened: list[str] = []
    connect = sqlite3.connect
    monkeypatch.setattr(store.sqlite3, "connect", lambda name, *a, **kw: opened.append(name) or connect(name, *a, **kw))
    code, out, err = grasp("best", "box", "--hand", "panda", "--db", str(db))
    assert code == 0 and out.startswith("#1 box/panda"), err
    assert opened and all(name.endswith("?mode=ro&immutable=1") for name in opened), opened
    assert any("in a read-only folder: read as it is now" in r.getMessage() for r in caplog.records)
    code, _, err = grasp("generate", "box", "--hand", "panda", "--db", str(db), *FAST, "--quiet")
    one_line_error(code, err, 3, "its folder is read-only", "nothing was changed")


def version_11_file(path: Path) -> None:
    """A database as version 11 wrote it: one object, no ``up`` column."""
    with sqlite3.connect(path) as conn:
        for statement in filter(str.strip, ";".join([SCHEMA, *(MIGRATIONS[v] for v in range(1, 11))]).split(";")):
            conn.execute(statement)
        conn.execute("INSERT INTO meta VALUES ('schema_version', '11')")
        conn.execute("INSERT INTO objects VALUES ('o', 's', 1, 'h', 1, 0.5, 1, 1, '[0,0,0]', '[0,0,0,0,0,0,0,0,0]', "
                     "0.1, '[1,1,1]')")


def test_objects_stored_before_version_12_are_z_up(tmp_path: Path) -> None:
    """Every object had +z as its up before the column: read-only (not migrated) and migrated alike."""
    old = tmp_path / "v11.db"
    version_11_file(old)
    with open_db(old, create=False, readonly=True) as db:
        assert db.meta("schema_version") == "11" and db.object_row("o").up == "+z"  # type: ignore[union-attr]
    with open_db(old) as db:
        assert db.meta("schema_version") == str(SCHEMA_VERSION) and db.object_row("o").up == "+z"  # type: ignore[union-attr]
    with sqlite3.connect(old) as conn:
        assert conn.execute("SELECT up FROM objects").fetchall() == [("+z",)]
    assert len(list(tmp_path.glob("v11.db.v11.*.bak"))) == 1


def test_objects_stored_before_version_13_are_of_their_collision_elements(tmp_path: Path) -> None:
    """A user's URDF could only be planned on its collision elements (where it had any) before the column:
    read-only and migrated alike."""
    old = tmp_path / "v12.db"
    version_11_file(old)
    with sqlite3.connect(old) as conn:
        conn.execute(MIGRATIONS[11])
        conn.execute("UPDATE meta SET value = '12' WHERE key = 'schema_version'")
    with open_db(old, create=False, readonly=True) as db:
        assert db.meta("schema_version") == "12" and db.object_row("o").geometry == "collision"  # type: ignore[union-attr]
    with open_db(old) as db:
        assert db.meta("schema_version") == str(SCHEMA_VERSION)
        assert db.object_row("o").geometry == "collision"  # type: ignore[union-attr]
    with sqlite3.connect(old) as conn:
        assert conn.execute("SELECT up, geometry FROM objects").fetchall() == [("+z", "collision")]


def test_grasps_stored_before_version_14_read_back_without_the_squeeze(box_db: Path, tmp_path: Path) -> None:
    """A version-13 file (the Panda's grasps, without the squeeze's columns): read-only and migrated, every
    grasp as stored, its squeeze's measures None (not measured)."""
    squeeze = ("squeezed_force_closure", "squeezed_epsilon", "squeeze_turn")
    def stored(db) -> list[dict]:  # type: ignore[no-untyped-def]
        return [g.to_json() for batch in db.grasp_batches("box", "panda") for g in batch]

    with open_db(box_db, create=False, readonly=True) as db:
        new = [g for batch in db.grasp_batches("box", "panda") for g in batch]
    assert any(g.measures.squeezed_force_closure is not None for g in new)  # type: ignore[union-attr]
    old = tmp_path / "v13.db"
    shutil.copy(box_db, old)
    with sqlite3.connect(old) as conn:
        for column in squeeze:
            conn.execute(f"ALTER TABLE grasps DROP COLUMN {column}")
        conn.execute("UPDATE meta SET value = '13' WHERE key = 'schema_version'")
    expected = [replace(g, measures=replace(g.measures, **dict.fromkeys(squeeze))).to_json()  # type: ignore[arg-type]
                for g in new]
    with open_db(old, create=False, readonly=True) as db:
        assert db.meta("schema_version") == "13" and stored(db) == expected
    with open_db(old) as db:
        assert db.meta("schema_version") == str(SCHEMA_VERSION) and stored(db) == expected


def test_a_reader_leaves_the_write_ahead_log_of_a_writer_that_migrated_the_file(tmp_path: Path) -> None:
    """The backup's copy opened and closed the file beside the migrating connection, and closing any descriptor
    drops the process's POSIX locks on the file: for the rest of the run SQLite's lock on it was gone, and a
    reader in another process (read-write since readers tidy up) took the file for its own at its close and
    deleted the -wal and -shm under the running `grasp generate`; its later commits went to the deleted log."""
    import subprocess
    import sys

    from processes import env

    old = tmp_path / "old.db"
    version_2_file(old)
    read = ("import sys\nfrom planner.db.store import open_db\n"
            "with open_db(sys.argv[1], create=False, readonly=True) as db:\n    print(db.meta('note'))")
    with open_db(old) as db:  # migrated after a backup copy; the writer goes on
        db.set_meta("note", "first")
        assert subprocess.run([sys.executable, "-c", read, str(old)], env=env(), capture_output=True, text=True,
                              check=True).stdout == "first\n"
        assert Path(f"{old}-wal").exists()
        db.set_meta("note", "second")
        assert subprocess.run([sys.executable, "-c", read, str(old)], env=env(), capture_output=True, text=True,
                              check=True).stdout == "second\n"
    assert len(list(tmp_path.glob("old.db.v2.*.bak"))) == 1


def test_a_version_14_file_migrates_its_grasps_and_trials_and_lets_a_squeezes_end_share_a_candidate(
        validated_db: Path, tmp_path: Path) -> None:
    """A v14 file (its grasps table keyed ``UNIQUE (unit_id, candidate)``, without ``squeezed_from_turn``) with
    trials: migrated, every grasp and trial as stored (the table built again keeps the ids the trials point at),
    ``squeezed_from_turn`` NULL; after it a squeeze's end may share its parent's unit and candidate, a second
    grasp closed where planned may not."""
    from planner.db.schema import _COLUMNS_V14, _GRASPS_V14

    old = tmp_path / "v14.db"
    shutil.copy(validated_db, old)
    with sqlite3.connect(old) as conn:  # the v14 table, as migration 13 left it
        conn.execute(f"CREATE TABLE v14 ({_GRASPS_V14}, UNIQUE (unit_id, candidate))")
        conn.execute(f"INSERT INTO v14 SELECT {_COLUMNS_V14} FROM grasps")
        conn.execute("PRAGMA foreign_keys = OFF")
        conn.execute("DROP TABLE grasps")
        conn.execute("ALTER TABLE v14 RENAME TO grasps")
        conn.execute("CREATE INDEX grasps_rank ON grasps (object, hand, rank)")
        conn.execute("UPDATE meta SET value = '14' WHERE key = 'schema_version'")

    def stored(path: Path) -> list[dict]:
        with open_db(path, create=False, readonly=True) as db:
            return [g.to_json() for o, h in db.pairs() for batch in db.grasp_batches(o, h) for g in batch]

    before = stored(old)
    assert sum(g["validation_success"] is not None for g in before) >= 3
    with open_db(old) as db:
        assert db.meta("schema_version") == str(SCHEMA_VERSION) == "16"
    assert stored(old) == before and all(g["squeezed_from_turn"] is None for g in before)
    with sqlite3.connect(old) as conn:
        assert conn.execute("PRAGMA foreign_key_check").fetchall() == []
        columns = [r[1] for r in conn.execute("PRAGMA table_info(grasps)")]
        row = conn.execute("SELECT * FROM grasps LIMIT 1").fetchone()
        end = dict(zip(columns, row), id=None, squeezed_from_turn=0.3)
        conn.execute(f"INSERT INTO grasps ({', '.join(end)}) VALUES ({', '.join('?' * len(end))})", list(end.values()))
        with pytest.raises(sqlite3.IntegrityError):
            conn.execute(f"INSERT INTO grasps ({', '.join(end)}) VALUES ({', '.join('?' * len(end))})",
                         list({**end, "squeezed_from_turn": None}.values()))
