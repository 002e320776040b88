"""Module-level unit functions for the pool tests (workers import them by name).

Units that wait do so on a file the test creates or on nothing at all:
the tests drive every moment by observed progress, never by wall time.
"""

from __future__ import annotations

import ctypes
import os
import signal
import time
from pathlib import Path

POLL = 0.01  # [s] between looks at a file another process will create


def square(x: int) -> int:
    return x * x


def crash(how: str) -> None:
    """Die the way a simulator or the kernel kills a worker."""
    if how == "segv":
        ctypes.string_at(0)  # read address 0: SIGSEGV
    elif how == "kill":
        os.kill(os.getpid(), signal.SIGKILL)
    else:
        os._exit(13)


def crash_first_time(args: tuple[str, str, int]) -> tuple[int, int]:
    """(folder, how, value): crash on the first attempt, return (value, pid)
    on the next. Each attempt leaves a file named by its pid."""
    folder, how, value = Path(args[0]), args[1], args[2]
    first = not any(folder.iterdir())
    (folder / str(os.getpid())).touch()
    if first:
        crash(how)
    return value, os.getpid()


def crash_always(args: tuple[str, str]) -> None:
    folder, how = Path(args[0]), args[1]
    (folder / str(os.getpid())).touch()
    crash(how)


def square_or_crash(unit: int | tuple[str, str]) -> int | None:
    return square(unit) if isinstance(unit, int) else crash_always(unit)


def square_crash_or_retry(unit: int | tuple) -> object:
    if isinstance(unit, int):
        return square(unit)
    return crash_first_time(unit) if len(unit) == 3 else crash_always(unit)


def block_or_square(unit: int | str) -> int:
    if isinstance(unit, str):
        block_forever(unit)
    return square(int(unit))


def fail(message: str) -> None:
    raise ValueError(message)


def unpicklable_result(_: int) -> object:
    return lambda: None


def wait_for(args: tuple[str, str, int]) -> int:
    """(mark, until, value): create ``mark`` (a file named by our pid in that
    folder when ``mark`` is a folder), wait until ``until`` exists, return
    ``value``."""
    mark, until, value = Path(args[0]), Path(args[1]), args[2]
    (mark / str(os.getpid()) if mark.is_dir() else mark).touch()
    while not until.exists():
        time.sleep(POLL)
    return value


def block_forever(progress: str) -> None:
    """Mark this worker as busy, then never finish."""
    (Path(progress) / str(os.getpid())).touch()
    while True:
        time.sleep(3600)


def in_flight(args: tuple[str, str]) -> tuple[int, int]:
    """(folder, release): hold a file in ``folder`` until ``release`` exists;
    return (files seen in ``folder`` on arrival, pid)."""
    folder, release = Path(args[0]), Path(args[1])
    mine = folder / f"{os.getpid()}.{time.monotonic_ns()}"
    mine.touch()
    seen = len(list(folder.iterdir()))
    while not release.exists():
        time.sleep(POLL)
    mine.unlink()
    return seen, os.getpid()



#: [s] how long :func:`note_then_wait` waits for its note to be heard (only a failing run waits it out).
NOTE_WAIT = 30.0


def note_then_wait(args: tuple[str, str]) -> bool:
    """(subject, heard): log a preparation line of ``subject``, then wait until ``heard`` exists; whether it came
    within :data:`NOTE_WAIT` (the driver's handler creates it when the line reaches it)."""
    from planner import prepare

    subject, heard = args
    prepare.noted(subject, "capped the mesh's open boundary loops (once: cached afterwards)")
    deadline = time.monotonic() + NOTE_WAIT
    while not Path(heard).exists() and time.monotonic() < deadline:
        time.sleep(POLL)
    return Path(heard).exists()
