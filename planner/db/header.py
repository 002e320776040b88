"""What a file given as a database is, told before SQLite writes to it, without a descriptor of its own."""

from __future__ import annotations

import shlex
import sqlite3
from contextlib import closing
from pathlib import Path
from urllib.parse import quote

from planner.errors import DatabaseError

#: [bytes] SQLite's smallest page: a database with anything in it is at least this long.
MIN_PAGE = 512


def uri(path: Path, query: str = "") -> str:
    """SQLite's URI of ``path``: its '?', '#' and '%' quoted (``--db "runs?1.db"`` was opened, and a writer
    created and wrote, "runs"; a reader said "not a grasp database" of a good one and left an empty "runs")."""
    return f"file:{quote(str(path))}" + (f"?{query}" if query else "")


def check_header(path: Path) -> None:
    """Refuse a file too short to be a database whose first bytes are not SQLite's (SQLite reads a file of a few
    bytes as an empty database, and a writer would write over it). A longer file is read by SQLite as immutable
    (its first page only: no lock, no -wal, -journal or -shm looked at or made), which says "file is not a
    database": opening and closing a descriptor of the file here dropped every POSIX lock SQLite holds on it in
    this process (a reader beside a writer of the same process, the Python API), and with them what keeps another
    process from checkpointing the WAL away under the writer; SQLite's own descriptors of a file are closed only
    once no connection of the process holds a lock on it. Left to the opening itself, SQLite replayed a -wal
    beside the file (a killed writer's, the file since replaced) into it before it looked at the first page."""
    if path.stat().st_size >= MIN_PAGE:
        try:
            with closing(sqlite3.connect(uri(path.resolve(), "mode=ro&immutable=1"), uri=True)) as conn:
                conn.execute("PRAGMA schema_version").fetchone()
        except sqlite3.DatabaseError as exc:  # anything else (damaged, truncated) is the opening's to say
            if str(exc) == "file is not a database":
                raise DatabaseError(_NOT_SQLITE.format(path=path)) from exc
        return
    with path.open("rb") as fh:
        if fh.read(16) != b"SQLite format 3\x00":
            raise DatabaseError(_NOT_SQLITE.format(path=path))


_NOT_SQLITE = "{path}: not an SQLite database; pick another --db path"


def cannot_open(path: Path, exc: sqlite3.DatabaseError) -> DatabaseError:
    """SQLite's error at opening ``path`` as the project's: its "file is not a database" as :func:`check_header`'s."""
    if str(exc) == "file is not a database":
        return DatabaseError(_NOT_SQLITE.format(path=path))
    if str(exc) == "database disk image is malformed":  # `grasp db check` of a truncated copy said only this
        return DatabaseError(f"{path}: cannot open database: {exc} (the file is truncated or damaged: nothing was "
                             f"changed; restore it from a copy, `sqlite3 {shlex.quote(str(path))} .recover` saves what "
                             "it can)")
    return DatabaseError(f"{path}: cannot open database: {exc}")


def look(path: Path) -> str:
    """SQLite's URI of a read-only look at ``path`` that makes nothing beside it. Without a -wal or -shm beside the
    file: the file as it is (immutable; a mode=ro opening of a WAL database makes both and cannot remove them when it
    closes: `generate` or `validate` of a truncated copy left them). Removing them afterwards removed those of a
    process that opened the file in the meantime (its next commit then lost). With either there: through them (a
    live writer's, or the committed units of a killed one), and both left as they are."""
    real = Path(path).resolve()
    if any(real.with_name(real.name + side).exists() for side in ("-wal", "-shm")):
        return uri(path, "mode=ro")
    return uri(real, "mode=ro&immutable=1")


def no_schema(path: Path, conn: sqlite3.Connection | None = None) -> DatabaseError:
    """The error for a file without a grasp database's schema (an empty file among them), or, while a `grasp
    generate` creates it, for a file whose schema is not written yet (a reader said "not a grasp database");
    ``conn``, the reader's connection to it, is closed."""
    from planner.db.lock import writer_of

    if conn is not None:
        conn.close()
    owner = writer_of(path)
    if owner is not None:
        return DatabaseError(f"{path}: no grasp is in it yet: {owner.doing('creating it')}; try again once its "
                             "first unit is written")
    return DatabaseError(f"{path}: not a grasp database (no schema); nothing was changed")
