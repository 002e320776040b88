"""One-time preparation a user waits for (a convex decomposition), announced,
and what it did to an object that the user should know (a repaired mesh, a
proxy that did not fit).

Each step logs an INFO line to the :data:`LOGGER` logger when it starts
(what, which object, that its result is cached) and when it ends (seconds);
:func:`noted` one line of what was done.
The library only logs; the CLI shows these lines on stderr
(:func:`planner.cli.app.show_preparation`), except under ``--quiet`` or
``--json``.
"""

from __future__ import annotations

import contextlib
import logging
import re
from collections.abc import Iterator

LOGGER = "planner.prepare"
log = logging.getLogger(LOGGER)

#: The end of :func:`ended`'s line: its seconds differ between two workers that both prepared one object.
_SECONDS = re.compile(r": done in [0-9.]+ s$")

#: What a CoACD run is called in the lines.
DECOMPOSITION = "convex decomposition (CoACD)"


def started(what: str, subject: str) -> None:
    log.info("%s of %s: started (once: cached afterwards)", what, subject)


def ended(what: str, subject: str, seconds: float) -> None:
    log.info("%s of %s: done in %.1f s", what, subject, seconds)


def noted(subject: str, what: str) -> None:
    log.info("%s: %s", subject, what)


def warned(line: str) -> None:
    """A line the user must see even under ``--quiet``: logged as a warning (the CLI shows it bare on stderr)."""
    log.warning("%s", line)


class _Kept(logging.Handler):
    def __init__(self, lines: list[str]) -> None:
        super().__init__(logging.INFO)
        self.lines = lines

    def emit(self, record: logging.LogRecord) -> None:
        self.lines.append(record.getMessage())


@contextlib.contextmanager
def kept(lines: list[str]) -> Iterator[None]:
    """The lines logged inside, appended to ``lines`` where nothing in this process shows them (a Ray worker: the
    driver says them, :func:`said`); else left to what shows them (a local pool's worker sends each to the driver
    as it is logged, :mod:`planner.run.worker`). A batch's objects are prepared in the
    workers: their notes (a mesh repaired, bodies standing apart), said once and then cached, were lost."""
    if log.hasHandlers():
        yield
        return
    handler, level = _Kept(lines), log.level
    log.addHandler(handler)
    log.setLevel(logging.INFO)
    try:
        yield
    finally:
        log.removeHandler(handler)
        log.setLevel(level)


def said(lines: list[str], before: set[str]) -> None:
    """Log ``lines`` (a worker's, :func:`kept`) here, each not in ``before`` (which gets them): two workers may
    both prepare an object the first time, and their "done in S s" lines are one line said once (both were
    said, with their two times)."""
    for line in lines:
        key = _SECONDS.sub(": done", line)
        if key not in before:
            before.add(key)
            log.info("%s", line)
