"""The writer lock: one process writes a database at a time.

SQLite itself serialises transactions; this lock makes a second ``grasp
generate`` (or ``validate``, ``import``) on the same file refuse at once with
a clear message instead of interleaving its units with the first one's.
"""

from __future__ import annotations

import fcntl
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from planner.errors import DatabaseError


@contextmanager
def writer_lock(db_path: Path) -> Iterator[None]:
    """One ``generate`` per database at a time: a second one refuses clearly."""
    lock_path = db_path.with_name(db_path.name + ".lock")
    try:
        fh = open(lock_path, "a+")
    except OSError as exc:
        raise DatabaseError(f"{db_path}: cannot create lock file {lock_path}: {exc}") from exc
    try:
        fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        fh.close()
        raise DatabaseError(f"{db_path}: another `grasp generate` is writing to this database; "
                            "wait for it to finish or use another --db") from None
    try:
        yield
    finally:
        fcntl.flock(fh, fcntl.LOCK_UN)
        fh.close()
