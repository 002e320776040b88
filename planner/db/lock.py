"""The writer lock: one process writes a database at a time,
``with writer_lock(db_path) as previous:``.

SQLite itself serialises transactions; this lock makes a second ``grasp
generate`` (or ``validate``, ``import``) on the same file refuse at once with
a clear message instead of interleaving its units with the first one's.

The lock is a BSD lock (``flock``) on ``<db>.lock``, held through one
descriptor that no other process keeps:

- the kernel drops it when the last descriptor of its open file closes,
  which happens when the owner dies, however it dies -- provided no other
  process holds a copy. Issue 13: ``ProcessPoolExecutor`` forked its workers
  and they inherited the descriptor, so they kept the lock after the driver
  was killed. Here the descriptor is close-on-exec (spawned workers, Ray,
  subprocesses never get it) and is closed in the child of every
  ``os.fork`` (multiprocessing's fork included) by an at-fork hook.
- ``flock`` belongs to the open file, so another open and close of the lock
  file by the same process (a backup, a test reading it) does not drop it.
  POSIX ``lockf`` locks would survive forks without the hook, but any
  close of any descriptor of the file in the owner silently drops them.

The owner writes one JSON line into the file (pid, process start, host,
command, since when); a busy lock is refused naming that owner, and a lock
taken while the file still names an owner (who died without releasing it)
is taken over with a warning that says whose it was.
"""

from __future__ import annotations

import errno
import fcntl
import json
import logging
import os
import socket
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass
from pathlib import Path

from planner.errors import DatabaseError
from planner.run import procs

log = logging.getLogger(__name__)



class LockBusy(DatabaseError):
    """Another live process is writing to the database."""


#: Descriptors of the locks this process holds.
_held: set[int] = set()


def _close_in_child() -> None:
    """After a fork: the child closes its copies (closing, not unlocking, which
    would release the parent's lock), so it never keeps the lock alive."""
    for fd in _held:
        try:
            os.close(fd)
        except OSError:
            pass
    _held.clear()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_close_in_child)


@dataclass(frozen=True)
class Owner:
    """Who holds (or held) a lock, as recorded in the lock file."""

    pid: int
    start: int | None  # process start, clock ticks since boot (Linux), for pid reuse
    host: str
    command: str
    since: float  # time.time() when the lock was taken

    @property
    def elsewhere(self) -> bool:
        """Whether it ran on another host, where this one cannot check whether it still runs."""
        return self.host != socket.gethostname()

    def describe(self) -> str:
        when = time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(self.since))
        where = f" on host {self.host}" if self.elsewhere else ""
        return f"pid {self.pid}{where}, `{self.command}`, since {when} ({_ago(time.time() - self.since)})"

    def doing(self, what: str) -> str:
        """``what`` said of it (``writing it``): as a fact where it runs on this host (:meth:`alive` checked it);
        for another host's, what its lock file records and that nothing here can tell whether it still runs (a
        container or machine that died leaves that record behind, which read as a writer at work)."""
        if not self.elsewhere:
            return f"{self.describe()} is {what}"
        return (f"its lock file records {self.describe()} as {what}, a process of another host, which this one "
                "cannot check: if it has ended, the next writer takes its lock over")

    @staticmethod
    def me() -> Owner:
        return Owner(os.getpid(), procs.start_ticks(os.getpid()), socket.gethostname(), _command(), time.time())

    @staticmethod
    def parse(text: str) -> Owner | None:
        try:
            d = json.loads(text)
            owner = Owner(int(d["pid"]), d.get("start"), str(d["host"]), str(d["command"]), float(d["since"]))
            time.localtime(owner.since)  # NaN, 1e300: no owner wrote that (describe() died on it, a traceback)
            return owner
        except (ValueError, KeyError, TypeError, OverflowError, OSError):
            return None

    def alive(self) -> bool:
        """False only if it certainly is not running (another host: unknown)."""
        return self.host != socket.gethostname() or procs.alive(self.pid, self.start)


def _ago(seconds: float) -> str:
    """A lapse of time as people say it: ``40 s ago``, ``12 min ago``, ``3.5 h ago``, ``2.0 days ago``."""
    if seconds < 0:
        return "in the future by this host's clock"
    for unit, size in (("days", 86400.0), ("h", 3600.0)):
        if seconds >= 2 * size:
            return f"{seconds / size:.1f} {unit} ago"
    return f"{seconds / 60:.0f} min ago" if seconds >= 120 else f"{seconds:.0f} s ago"


#: Characters of a command kept in the lock (what a refused second writer is told).
COMMAND_CHARS = 200


def _command() -> str:
    """This process's command: ``grasp generate box random_001 --hand panda`` (cut at
    :data:`COMMAND_CHARS`)."""
    if not sys.argv or not sys.argv[0]:
        return "python"
    program = Path(sys.argv[0]).name
    if program == "__main__.py":  # python -m package
        spec = getattr(sys.modules.get("__main__"), "__spec__", None)
        program = f"python -m {spec.name.removesuffix('.__main__')}" if spec else "python"
    text = " ".join([program, *sys.argv[1:]])
    return text if len(text) <= COMMAND_CHARS else text[:COMMAND_CHARS - 3] + "..."


@contextmanager
def writer_lock(db_path: Path) -> Iterator[Owner | None]:
    """Hold the database's writer lock; yields the previous owner if its
    lock was taken over (it died while writing), else None. Raises
    :class:`LockBusy` if a live process holds it."""
    db_path = Path(db_path)
    real = db_path.resolve()  # one lock per file, by whichever path (a symlink) it is named
    lock_path = real.with_name(real.name + ".lock")
    try:
        fd = os.open(lock_path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
    except OSError as exc:
        raise DatabaseError(f"{db_path}: cannot create the lock file {lock_path}: {exc.strerror}") from None
    try:
        _lock(fd, db_path)
        _held.add(fd)
        previous = _read(fd)
        if previous is not None:
            ended = "which holds it no longer (a process of another host, which this one cannot check: ended, or " \
                "that host's lock is not seen here)" if previous.elsewhere else "which ended without releasing it"
            log.warning("%s: taking over the writer lock of %s, %s; its unfinished work is done again", db_path,
                        previous.describe(), ended)
        _write(fd, json.dumps(asdict(Owner.me())))
        try:
            yield previous
        finally:
            _write(fd, "")  # released cleanly: nothing to take over
            _held.discard(fd)
            fcntl.flock(fd, fcntl.LOCK_UN)
    finally:
        os.close(fd)


def writer_of(db_path: Path) -> Owner | None:
    """The live process writing ``db_path`` as its lock file names it (None: none, or no lock file to read). Read
    without taking the lock: a reader must not make a starting writer refuse."""
    real = Path(db_path).resolve()
    try:
        text = real.with_name(real.name + ".lock").read_text(errors="replace").strip()
    except OSError:
        return None
    owner = Owner.parse(text) if text else None
    return owner if owner is not None and owner.alive() else None


def _lock(fd: int, db_path: Path) -> None:
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as exc:
        if exc.errno not in (errno.EAGAIN, errno.EACCES):
            raise DatabaseError(f"{db_path}: cannot lock {db_path.name}.lock: {exc.strerror}") from None
        owner = _read(fd)
        if owner is not None and owner.pid == os.getpid():
            raise LockBusy(f"{db_path}: this process is already writing to this database") from None
        if owner is None:
            who = "a process that has not recorded its pid yet"
        elif owner.alive():
            who = owner.describe()
        else:  # a descriptor copied by a C-level fork() in the owner (see the module docstring)
            who = f"a process left behind by {owner.describe()}, which has ended"
        raise LockBusy(f"{db_path}: another process ({who}) is writing to this database; "
                       "wait for it to finish or use another --db") from None


def _read(fd: int) -> Owner | None:
    text = os.pread(fd, 4096, 0).decode(errors="replace").strip()
    return Owner.parse(text) if text else None


def _write(fd: int, text: str) -> None:
    os.ftruncate(fd, 0)
    os.pwrite(fd, text.encode(), 0)
