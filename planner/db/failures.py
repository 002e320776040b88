"""What SQLite refuses, as one line each: a write (why, what is kept, what
to do) and a read (:func:`_reads`, the decorator every read of
:class:`~planner.db.store.Database` wears).
"""

from __future__ import annotations

import contextlib
import functools
import inspect
import shlex
import sqlite3
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from planner.errors import DatabaseError

if TYPE_CHECKING:
    from planner.db.store import Database


def write_failed(path: Path, exc: sqlite3.Error, kept: int | None) -> str:
    """The one line for a write SQLite refused: why, what is kept, what to do.
    SQLite rolls the failed transaction back, so every commit before it stays."""
    name, text = getattr(exc, "sqlite_errorname", ""), str(exc)  # the name: Python >= 3.11
    if name.startswith(("SQLITE_CORRUPT", "SQLITE_NOTADB")) or "malformed" in text:  # "disk image": not the disk
        cause, fix = "the database file is damaged", "check it with `grasp db check`"
    elif name.startswith("SQLITE_READONLY") or "readonly" in text:
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


def read_failed(path: Path, exc: sqlite3.Error) -> str:
    """The one line for a read SQLite refused (a damaged file, an I/O error)."""
    return f"{path}: cannot read the database ({exc}); check it with `grasp db check --db {shlex.quote(str(path))}`"


def missing(path: Path) -> str:
    """The one line for a database that is not there."""
    return f"{path}: no such database; run `grasp generate ... --db {shlex.quote(str(path))}` first"


def no_grasps(path: Path, objects: list[str]) -> str:
    """The one line for a database without a grasp: generate first, or, where it holds ``objects`` whose sweeps
    kept none (validate and report of such a database said "run `grasp generate` first"), where to read why."""
    db = shlex.quote(str(path))
    if not objects:
        return f"no grasps in {path}; run `grasp generate ... --db {db}` first"
    return (f"no grasps in {path}: the sweeps of its objects ({', '.join(objects)}) kept none; `grasp best "
            f"{shlex.quote(objects[0])} --hand HAND --db {db}` says why")


F = TypeVar("F", bound=Callable[..., Any])


def _reads(method: F) -> F:
    """A read of the database: SQLite's errors come out as one
    :class:`DatabaseError` line (a generator's, while it is iterated)."""
    if inspect.isgeneratorfunction(method):
        @functools.wraps(method)
        def rows(self: Database, *args: Any, **kwargs: Any) -> Iterator[Any]:
            inner = method(self, *args, **kwargs)
            while True:
                try:
                    item = next(inner)
                except StopIteration:
                    return
                except sqlite3.Error as exc:
                    raise DatabaseError(read_failed(self.path, exc)) from exc
                try:
                    yield item
                except GeneratorExit:  # dropped (an error or Ctrl-C elsewhere), maybe after its connection closed:
                    with contextlib.suppress(sqlite3.Error):  # nothing is left to read, and nothing is wrong
                        inner.close()
                    raise
        return rows  # type: ignore[return-value]

    @functools.wraps(method)
    def read(self: Database, *args: Any, **kwargs: Any) -> Any:
        try:
            return method(self, *args, **kwargs)
        except sqlite3.Error as exc:
            raise DatabaseError(read_failed(self.path, exc)) from exc
    return read  # type: ignore[return-value]
