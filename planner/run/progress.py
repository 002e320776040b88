"""Progress inside running units: how a unit says how far it is, and how the
driver adds the units' counts into one figure for a progress bar.

A unit function called with a ``report`` calls ``report(done, total)`` as it
goes: ``done`` of its ``total`` steps (``generate``: candidates) are finished.
:class:`Throttled` passes on the first call, the last (``done == total``) and
others at most every :data:`INTERVAL` seconds, so a pipe to the driver carries
a few messages a second whatever the unit's pace. Reports never feed back into
a unit: its result is the same with or without them.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

#: report(done, total): ``done`` of the unit's ``total`` steps are finished.
Report = Callable[[int, int], None]
#: [s] at most one report between a unit's first and last passes this often.
INTERVAL = 0.5


class Throttled:
    """A :data:`Report` that forwards to ``send`` the first call, the last
    (``done >= total``) and otherwise one call per :data:`INTERVAL`."""

    def __init__(self, send: Report, interval: float = INTERVAL) -> None:
        self.send, self.interval = send, interval
        self.last: float | None = None

    def __call__(self, done: int, total: int) -> None:
        now = time.monotonic()
        if self.last is None or done >= total or now - self.last >= self.interval:
            self.last = now
            self.send(done, total)


class Tally:
    """Steps done and to do over a batch of units, for one progress bar.

    ``planned[i]`` is unit ``i``'s expected total (None: not known before it
    runs); a unit's own report replaces it. A unit not yet reported and not
    planned counts as the mean of the known totals (the total is None while
    none is known). ``done`` counts a finished unit (done, failed or out of
    retries) as its whole total, and a running unit as the most it has
    reported over its attempts: a retry after a crash counts again from zero
    but adds nothing until it passes the crashed attempt, so ``done`` never
    goes down and never counts a step twice.
    """

    def __init__(self, planned: Sequence[int | None]) -> None:
        self.totals: list[int | None] = list(planned)
        self.reached = [0] * len(self.totals)

    def report(self, index: int, done: int, total: int) -> None:
        self.totals[index] = total
        self.reached[index] = min(max(self.reached[index], done), total)

    def finish(self, index: int) -> None:
        """Unit ``index`` is over: it counts as its whole total (0 if it never
        said and none was planned: it failed before it began)."""
        total = self.totals[index]
        self.totals[index] = total = total if total is not None else 0
        self.reached[index] = total

    @property
    def done(self) -> int:
        return sum(self.reached)

    @property
    def total(self) -> int | None:
        known = [t for t in self.totals if t is not None]
        if not known:
            return None if self.totals else 0
        unknown = len(self.totals) - len(known)
        return max(sum(known) + round(unknown * sum(known) / len(known)), self.done)
