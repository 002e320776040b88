"""The ``grasp`` command: parse, call :mod:`planner.api`, print.

Errors become one line on stderr and an exit code (2 bad input, 3 database,
4 simulator, 1 anything else); ``grasp --debug ...`` shows the traceback.
Commands, one module per group of them: ``generate``; ``best``, ``show``
(query); ``view`` (the browser viewer); ``validate``, ``report``; ``calibrate``; ``export``, ``import``
(data); ``hands``, ``objects``, ``db check`` (info).

Importing this package imports nothing: :func:`run`, the console script's entry point (and ``python -m
planner.cli``'s), imports the commands (click, numpy, the specs: ~0.25 s) inside it, so a Ctrl-C (or a SIGTERM)
while they load ends as one during a command does (exit 130, one line), not with a traceback. ``main``, the click
group with every command, is loaded on first use.
"""

from __future__ import annotations

import sys
from collections.abc import Callable  # not typing: its import (~10 ms) is a window for a traceback
from types import FrameType  # loaded already, by the site module

#: 128 + SIGINT, as shells report a command ended by Ctrl-C.
EXIT_INTERRUPTED = 130


def run() -> None:
    """The ``grasp`` command as the console script starts it. SIGTERM ends it as Ctrl-C does from the start
    (:func:`terminated`; the group sets it too, for callers of ``main``): before, while the commands loaded and
    click read the arguments, it killed the process without a word (exit -15)."""
    import atexit
    import signal

    signal.signal(signal.SIGTERM, terminated)
    atexit.register(_last)  # before any hook of the command's: run after them all
    try:
        command = _main()
        command()  # always exits: every error and interruption past the imports is the group's (``app.Group``)
    except KeyboardInterrupt:
        print("grasp: interrupted; nothing was changed", file=sys.stderr)
        sys.exit(EXIT_INTERRUPTED)
    except SystemExit as done:
        if done.code == EXIT_INTERRUPTED:
            _settled()
        raise


def _settled() -> None:
    """An interrupted run has said so and chosen its exit code: a second Ctrl-C or SIGTERM while the interpreter
    shuts down (worker processes joined, the database closed) ends it at once with that code (:func:`_now`). It
    ended the process by SIGINT (exit -2, no line) once Python had put back the default handler, or with an
    "Exception ignored" traceback, where a batch script checks for 130."""
    import signal

    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, _now)


def _last() -> None:
    """The interpreter's last exit hook of an interrupted run: a second signal from here on is ignored, and the
    run ends with its 130 a moment later. Past the hooks Python puts back the default action of a signal it has
    a handler of (not of one it ignores) while it tears the modules down: a second Ctrl-C there ended the run by
    SIGINT (exit -2, a `generate --workers 2` 0.05-0.2 s after the first)."""
    import signal

    if signal.getsignal(signal.SIGINT) is _now:
        for signum in (signal.SIGINT, signal.SIGTERM):
            signal.signal(signum, signal.SIG_IGN)


def _now(signum: int, frame: FrameType | None) -> None:
    """Exit 130 now: what was committed is in the database (SQLite's WAL survives any exit), the writer lock is
    the kernel's to drop, and worker processes end with their parent (``planner.run.procs``)."""
    import os

    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # closed, or the reader went away
            pass
    os._exit(EXIT_INTERRUPTED)


#: [s] how soon a SIGTERM that arrived inside a destructor is delivered again.
TERM_RETRY = 0.05


def terminated(signum: int, frame: FrameType | None) -> None:
    """SIGTERM (``timeout``, a scheduler, systemd) ends a run as Ctrl-C does: cleanly, with its one line. Python
    drops an exception raised inside a destructor ("Exception ignored in ... __del__": the run went on to its
    end, exit 0, a fresh-clone CI run saw it): there the signal is sent again a moment later."""
    while frame is not None:
        if frame.f_code.co_name == "__del__":
            import os
            import threading

            threading.Timer(TERM_RETRY, os.kill, (os.getpid(), signum)).start()
            return
        frame = frame.f_back
    raise KeyboardInterrupt


def _main() -> Callable[[], object]:
    """The click group with every command (imported here: the heavy part of starting)."""
    from planner.cli.app import main
    from planner.cli.calibrate import calibrate
    from planner.cli.data import export, import_files
    from planner.cli.generate import generate
    from planner.cli.info import db, hands, objects
    from planner.cli.query import best, show
    from planner.cli.validate import report, validate
    from planner.cli.view import view

    for command in (generate, best, show, view, validate, report, calibrate, export, import_files, hands, objects, db):
        main.add_command(command)
    return main


def __getattr__(name: str) -> object:
    if name == "main":
        return _main()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["main", "run"]
