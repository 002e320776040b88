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

import logging

LOGGER = "planner.prepare"
log = logging.getLogger(LOGGER)

#: What a CoACD run is called in the lines.
DECOMPOSITION = "convex decomposition (CoACD)"


def started(what: str, subject: str) -> None:
    log.info("%s of %s: started (once: cached afterwards)", what, subject)


def ended(what: str, subject: str, seconds: float) -> None:
    log.info("%s of %s: done in %.1f s", what, subject, seconds)


def noted(subject: str, what: str) -> None:
    log.info("%s: %s", subject, what)
