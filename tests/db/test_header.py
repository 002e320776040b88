"""planner.db.header: a file given as a database, told apart without dropping this process's SQLite locks."""

from __future__ import annotations

import sqlite3
import subprocess
import sys
from contextlib import closing
from pathlib import Path

import pytest

from planner.db.store import open_db
from planner.errors import DatabaseError

#: SQLite's unix VFS: a SHARED lock is a read lock on these bytes of the database file (sqlite3.c, SHARED_FIRST).
SHARED_FIRST, SHARED_SIZE = 0x40000000 + 2, 510

#: Another process asks for a write lock over SQLite's SHARED range: refused while this one reads.
PROBE = f"""
import fcntl, sys
with open(sys.argv[1], "rb+") as fh:
    try:
        fcntl.lockf(fh, fcntl.LOCK_EX | fcntl.LOCK_NB, {SHARED_SIZE}, {SHARED_FIRST})
    except OSError:
        print("locked")
    else:
        print("free")
"""


def _probe(path: Path) -> str:
    return subprocess.run([sys.executable, "-c", PROBE, str(path)], capture_output=True, text=True,
                          check=True).stdout.strip()


def test_a_reader_in_the_writers_process_keeps_the_writers_locks(box_db: Path, tmp_path: Path) -> None:
    """The Python API's reader (open_db) read the file's first bytes through a descriptor of its own and closed
    it: POSIX locks are the process's, so that close dropped the SQLite locks a writer in the same process held,
    and another process could take the file (checkpoint and remove the WAL) under it."""
    path = tmp_path / "g.db"
    path.write_bytes(box_db.read_bytes())
    writer = sqlite3.connect(path, isolation_level=None)
    try:
        writer.execute("BEGIN")
        writer.execute("SELECT count(*) FROM grasps").fetchone()  # a read transaction: SHARED on the file
        assert _probe(path) == "locked"
        with open_db(path, create=False, readonly=True) as db:
            assert db.integrity_check() == []
        assert _probe(path) == "locked"
    finally:
        writer.close()


@pytest.mark.parametrize("content", [b"x", b"my precious notes", b"\x00not a database at all" * 100])
def test_a_file_that_is_not_sqlite_is_refused_in_one_line_and_untouched(tmp_path: Path, content: bytes) -> None:
    """Short or long, read or written: SQLite's own "file is not a database" is said as before; a 1-byte file,
    which SQLite reads as an empty database, is refused before SQLite could write over it."""
    path = tmp_path / "notes.db"
    path.write_bytes(content)
    for readonly in (True, False):
        with pytest.raises(DatabaseError, match=f"^{path}: not an SQLite database; pick another --db path$"):
            open_db(path, readonly=readonly)
    assert path.read_bytes() == content


def test_db_check_of_a_truncated_or_damaged_file_says_what_to_do(box_db: Path, tmp_path: Path) -> None:
    """`grasp db check` of a copy cut short said "cannot open database: database disk image is malformed" and no
    more; of one with a damaged page "(1 problems, listed on stdout)"."""
    from helpers import grasp, one_line_error

    cut = tmp_path / "cut.db"
    cut.write_bytes(box_db.read_bytes()[:3000])
    code, _, err = grasp("db", "check", "--db", str(cut))
    one_line_error(code, err, 3, f"{cut}: cannot open database: database disk image is malformed (the file is "
                   f"truncated or damaged: nothing was changed; restore it from a copy, `sqlite3 {cut} .recover` "
                   "saves what it can)")
    assert cut.read_bytes() == box_db.read_bytes()[:3000]
    damaged = tmp_path / "damaged.db"
    data = bytearray(box_db.read_bytes())
    with closing(sqlite3.connect(f"file:{box_db}?mode=ro", uri=True)) as conn:  # a page of grasps, not the schema's
        page = conn.execute("SELECT MAX(pageno) FROM dbstat WHERE name = 'grasps' AND pagetype = 'leaf'").fetchone()[0]
        size = conn.execute("PRAGMA page_size").fetchone()[0]
    data[(page - 1) * size:page * size] = bytes(range(256)) * (size // 256)
    damaged.write_bytes(bytes(data))
    code, out, err = grasp("db", "check", "--db", str(damaged))
    assert code == 3 and f"{damaged}: integrity check failed (1 problem, listed on stdout)" in err, err
    assert out.strip()


def test_a_wal_beside_a_file_that_is_not_sqlite_is_not_replayed_into_it(box_db: Path, tmp_path: Path) -> None:
    """A killed writer's -wal, the database since replaced by another file: SQLite, left to see what the file is
    when it opened it, replayed the WAL into the file first (100 kB of notes cut to 76 kB, the WAL removed) and
    `grasp best` said "database disk image is malformed ... nothing was changed"."""
    path = tmp_path / "g.db"
    path.write_bytes(box_db.read_bytes())
    writer = sqlite3.connect(path, isolation_level=None)
    writer.execute("PRAGMA journal_mode = WAL")
    writer.execute("PRAGMA wal_autocheckpoint = 0")
    writer.execute("CREATE TABLE extra (x)")  # the schema is on the first page: it is in the WAL
    wal = path.with_name("g.db-wal").read_bytes()
    writer.close()
    path.with_name("g.db-wal").write_bytes(wal)
    notes = b"my notes\n" * 12_000
    path.write_bytes(notes)
    for readonly in (True, False):
        with pytest.raises(DatabaseError, match=f"^{path}: not an SQLite database; pick another --db path$"):
            open_db(path, create=False, readonly=readonly)
    assert path.read_bytes() == notes
    assert path.with_name("g.db-wal").read_bytes() == wal
    assert sorted(p.name for p in tmp_path.iterdir()) == ["g.db", "g.db-wal"]


@pytest.mark.parametrize("name", ["runs?1.db", "a#b.db", "100%20.db"])
def test_a_database_whose_name_has_uri_characters_is_that_file(box_db: Path, tmp_path: Path, name: str) -> None:
    """SQLite's URI took "runs?1.db" for "runs" (and "100%20.db" for "100 .db"): a reader said "not a grasp
    database (no schema)" of a good database and left an empty "runs" beside it; a writer wrote into "runs"."""
    from planner.db.store import open_for_writing

    path = tmp_path / name
    path.write_bytes(box_db.read_bytes())
    with open_db(path, create=False, readonly=True) as db:
        assert db.object_names() == ["box"]
    with open_for_writing(path, create=False) as db:
        assert db.object_names() == ["box"]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([name, f"{name}.lock"])


def test_validate_of_an_empty_file_refuses_and_leaves_it_as_it_was(tmp_path: Path) -> None:
    """`grasp validate --db empty.db` on a 0-byte file made it a database and left a .lock beside it; the readers
    refused it. Now validate refuses it too, changing nothing (`generate` into a 0-byte file still makes one)."""
    from helpers import FAST, grasp, one_line_error

    db = tmp_path / "empty.db"
    db.write_bytes(b"")
    code, _, err = grasp("validate", "--db", str(db))
    one_line_error(code, err, 3, "empty.db: not a grasp database (no schema)", "nothing was changed")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["empty.db"] and db.stat().st_size == 0
    code, _, err = grasp("generate", "sphere", "--hand", "panda", "--db", str(db), *FAST, "--quiet")
    assert code == 0 and db.stat().st_size > 0, err


@pytest.mark.parametrize("command", ["generate", "validate"])
def test_a_truncated_database_refused_by_a_writer_leaves_no_wal_or_shm(box_db: Path, tmp_path: Path,
                                                                       command: str) -> None:
    """`generate` or `validate` on a truncated copy refused it (the file unchanged) and left an empty -wal and a
    -shm beside it: SQLite's read-only look at a WAL database makes both and cannot remove them."""
    from helpers import FAST, grasp, one_line_error

    db = tmp_path / "cut.db"
    db.write_bytes(box_db.read_bytes()[:40_000])
    before = db.read_bytes()
    args = ("generate", "box", "--hand", "panda", *FAST, "--quiet") if command == "generate" else ("validate",)
    code, _, err = grasp(*args, "--db", str(db))
    one_line_error(code, err, 3, "cut.db: cannot open database", "nothing was changed")
    assert db.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir() if p.name != "cut.db.lock") == ["cut.db"]


def test_a_reader_of_a_file_being_created_says_so(tmp_path: Path) -> None:
    """While `grasp generate` creates a new file, `api.best` from another process said "not a grasp database (no
    schema)" of it. The writer's lock names who is creating it: said, and when to try again."""
    from planner import api
    from planner.db.lock import writer_lock

    db = tmp_path / "new.db"
    db.write_bytes(b"")  # as SQLite leaves it between creating the file and writing its schema
    creating = r"new.db: no grasp is in it yet: pid \d+.* is creating it; try again once"
    with writer_lock(db), pytest.raises(DatabaseError, match=creating):
        api.best("box", "panda", db_path=db)
    with pytest.raises(DatabaseError, match=r"new.db: not a grasp database \(no schema\)"):
        api.best("box", "panda", db_path=db)


def test_best_while_a_run_writes_the_object_says_so(box_db: Path, tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """`grasp best duck` while `grasp generate duck` was writing the database, none of its units finished yet,
    said "run `grasp generate duck --hand panda --db ...`": the very run that was going on. It says who writes."""
    import shutil

    from planner import api
    from planner.db.lock import writer_lock
    from planner.errors import InputError

    db = tmp_path / "g.db"
    shutil.copy(box_db, db)
    monkeypatch.setattr(sys, "argv", ["grasp", "generate", "sphere", "--hand", "panda", "--db", str(db)])
    with writer_lock(db), pytest.raises(InputError, match=r"no grasps of 'sphere' for hand 'panda' in .*g.db yet: "
                                                          r"pid \d+.* is writing it; try again once a unit"):
        api.best("sphere", "panda", db_path=db)
    with pytest.raises(InputError, match=r"no grasps of 'sphere' .* run `grasp generate sphere"):
        api.best("sphere", "panda", db_path=db)


#: Another application opens its WAL database (SQLite makes an empty -wal and a -shm), waits for a line, then commits
#: a row and dies without closing (the row only in its -wal, as a killed writer's units are).
APP = """
import os, sqlite3, sys
conn = sqlite3.connect(sys.argv[1], isolation_level=None)
conn.execute("SELECT COUNT(*) FROM t").fetchone()
print("open", flush=True)
sys.stdin.readline()
conn.execute("INSERT INTO t VALUES (1)")
print("committed", flush=True)
os._exit(0)
"""


def test_a_refused_look_keeps_the_wal_of_a_writer_that_opened_meanwhile(tmp_path: Path,
                                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    """The look at a file before its writer's lock removed an empty -wal and a -shm that were not there when it
    began: another process that opened the file in the meantime (not yet written: its -wal is empty) lost both, and
    its next commit went into a -wal no one else could see (its row gone once it died). The look makes none."""
    from planner.db import store
    from planner.db.store import open_for_writing

    db = tmp_path / "app.db"
    with closing(sqlite3.connect(db)) as conn:  # another application's WAL database, closed: no -wal, no -shm
        conn.execute("PRAGMA journal_mode = WAL")
        conn.execute("CREATE TABLE t (x)")
        conn.commit()
    app = subprocess.Popen([sys.executable, "-c", APP, str(db)], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                           text=True)
    look = store.schema_version

    def meanwhile(conn: sqlite3.Connection, path: Path) -> int:  # the application opens while the look reads
        assert app.stdout is not None and app.stdout.readline() == "open\n"
        return look(conn, path)

    monkeypatch.setattr(store, "schema_version", meanwhile)
    try:
        with pytest.raises(DatabaseError, match="an SQLite file, but not a grasp database"), \
                open_for_writing(db, create=False):
            pass
    finally:
        out, _ = app.communicate("\n", timeout=30)
    assert out == "committed\n"
    with closing(sqlite3.connect(db)) as conn:
        assert conn.execute("SELECT COUNT(*) FROM t").fetchone()[0] == 1


def test_best_of_an_object_no_running_sweep_writes_says_to_generate_it(box_db: Path, tmp_path: Path,
                                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    """Any writer of the database (a `grasp validate`, a generate of another object or hand) made `best sphere` say
    "pid N, `grasp validate ...` is writing it; try again once a unit of it has finished": waiting never gives a
    grasp. Only a run that sweeps the object for the hand is said to write it; else: run `grasp generate ...`."""
    import shutil

    from planner import api
    from planner.db.lock import writer_lock
    from planner.errors import InputError

    db = tmp_path / "g.db"
    shutil.copy(box_db, db)
    for argv in (["grasp", "validate", "--db", str(db)], ["grasp", "generate", "sphere", "--hand", "barrett"],
                 ["grasp", "generate", "box", "--hand", "panda", "--db", str(db)]):
        monkeypatch.setattr(sys, "argv", argv)
        with writer_lock(db), pytest.raises(InputError) as refused:
            api.best("sphere", "panda", db_path=db)
        assert "is writing it" not in str(refused.value) and "run `grasp generate sphere" in str(refused.value)
    monkeypatch.setattr(sys, "argv", ["grasp", "generate", "box", "sphere", "--hand", "panda", "--db", str(db)])
    with writer_lock(db), pytest.raises(InputError, match=r"yet: pid \d+, `grasp generate box sphere .* is writing it"):
        api.best("sphere", "panda", db_path=db)
