"""The worker side of :mod:`planner.run.pool`: one process, one pipe to the driver.

Protocol (driver -> worker): ``(index, unit)`` to run, ``None`` to stop.
(worker -> driver): ``("ready", pid)`` once, then per unit
``("ok", index, result, seconds)`` or ``("error", index, message, seconds)``,
after any number of ``("progress", index, done, total)`` when the pool asked
for progress (``fn`` is then called as ``fn(unit, report)``, the report
throttled by :class:`planner.run.progress.Throttled`), and of ``("note",
line)``: a line :mod:`planner.prepare` logged (a mesh closed, once: cached
afterwards), sent as it is logged, so a run stopped before the unit's end
has said it.

A worker never outlives its driver: a watcher thread exits it when the
*lifeline* -- a pipe whose only write end the driver holds and never writes --
reads EOF, however the driver died; on Linux the kernel also SIGKILLs it
(``PR_SET_PDEATHSIG``) even when that thread cannot run.
"""

from __future__ import annotations

import logging
import os
import signal
import threading
import time
from collections.abc import Callable
from multiprocessing.connection import Connection
from typing import Any

from planner import prepare
from planner.run import procs
from planner.run.progress import Throttled

#: Exit status of a worker that noticed its driver is gone.
ORPHANED = 70
#: What ``ps`` and ``top`` show for a worker (Linux).
NAME = "grasp-worker"


def describe(exc: BaseException) -> str:
    """One line for a unit's exception (the same in and out of process)."""
    return f"{type(exc).__name__}: {'; '.join(str(exc).splitlines())}"


class _Notes(logging.Handler):
    """:mod:`planner.prepare`'s lines, each sent to the driver as it is logged."""

    def __init__(self, conn: Connection) -> None:
        super().__init__(logging.INFO)
        self.conn = conn

    def emit(self, record: logging.LogRecord) -> None:
        self.conn.send(("note", record.getMessage()))


def _send_notes(conn: Connection) -> None:
    log = logging.getLogger(prepare.LOGGER)
    log.addHandler(_Notes(conn))
    log.setLevel(logging.INFO)
    log.propagate = False  # said by the driver, not here too


def _exit_when_driver_dies(lifeline: Connection) -> None:
    """The portable tie to the driver, and the only one that works under
    forkserver (the fork server, not the driver, is the worker's parent)."""
    try:
        lifeline.recv_bytes()
    except (EOFError, OSError):
        pass
    os._exit(ORPHANED)


def main(fn: Callable[..., Any], conn: Connection, lifeline: Connection, pdeathsig: bool,
         report: bool = False) -> None:
    """Entry point of a worker process (started with spawn or forkserver)."""
    if pdeathsig:
        procs.die_with_parent()
    procs.set_name(NAME)
    # Started after the prctl, the watcher also covers a driver that died
    # before it was armed: its read then returns at once.
    threading.Thread(target=_exit_when_driver_dies, args=(lifeline,), daemon=True).start()
    # Ctrl-C reaches the whole foreground process group; only the driver acts
    # on it (it stops the workers), so a unit is never cut short half-written.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _send_notes(conn)
    conn.send(("ready", os.getpid()))
    while True:
        try:
            message = conn.recv()
        except (EOFError, OSError):  # the driver is gone
            return
        if message is None:
            return
        index, unit = message
        start = time.perf_counter()
        try:
            if report:
                def send(done: int, total: int, index: int = index) -> None:
                    conn.send(("progress", index, done, total))

                reply = ("ok", index, fn(unit, Throttled(send)), time.perf_counter() - start)
            else:
                reply = ("ok", index, fn(unit), time.perf_counter() - start)
        except Exception as exc:  # reported as this unit's failure; the worker goes on
            reply = ("error", index, describe(exc), time.perf_counter() - start)
        try:
            conn.send(reply)
        except Exception as exc:  # e.g. an unpicklable result: nothing was written yet
            conn.send(("error", index, f"result could not be sent back: {describe(exc)}",
                       time.perf_counter() - start))
