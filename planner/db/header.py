"""What a file given as a database is, told before SQLite writes to it, without a descriptor of its own."""

from __future__ import annotations

import shlex
import sqlite3
from collections.abc import Iterator
from contextlib import closing, contextmanager
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


@contextmanager
def nothing_left_if_refused(path: Path) -> Iterator[None]:
    """A look at ``path`` that, refused (a :class:`DatabaseError`: a truncated or damaged file), leaves no ``-wal``
    and ``-shm`` beside it that were not there before: SQLite's read-only opening of a WAL database makes both,
    and cannot remove them when it closes (`generate` or `validate` of a truncated copy left an empty -wal and a
    -shm; the file itself was unchanged). A -wal with something in it is kept: it may be someone's data."""
    real = Path(path).resolve()
    wal, shm = (real.with_name(real.name + side) for side in ("-wal", "-shm"))
    there = wal.exists() or shm.exists()
    try:
        yield
    except DatabaseError:
        if not there and (not wal.exists() or wal.stat().st_size == 0):
            wal.unlink(missing_ok=True)
            shm.unlink(missing_ok=True)
        raise


def no_schema(path: Path, conn: sqlite3.Connection | None = None) -> DatabaseError:
    """The error for a file without a grasp database's schema (an empty file among them), or, while a `grasp
    generate` creates it, for a file whose schema is not written yet (a reader said "not a grasp database");
    ``conn``, the reader's connection to it, is closed."""
    from planner.db.lock import writer_of

    if conn is not None:
        conn.close()
    owner = writer_of(path)
    if owner is not None:
        return DatabaseError(f"{path}: being created by {owner.describe()}; no grasp is in it yet: try again once "
                             "its first unit is written")
    return DatabaseError(f"{path}: not a grasp database (no schema); nothing was changed")
