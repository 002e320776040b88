"""Unit functions for bench/pool.py (module-level, so workers import them by name)."""

from __future__ import annotations

import os
import time
from pathlib import Path


def square(x: int) -> int:
    return x * x


def with_planner(x: int) -> int:
    """A unit that needs the planner's imports, as every real unit does."""
    import planner.plan.unit  # noqa: F401  (already there in a preloaded fork-server worker)

    return x


def crash_once(mark: str) -> float:
    """First attempt: note the time and die. Retry: seconds since that death
    (replacing the worker, its imports and sending the unit again)."""
    import planner.plan.unit  # noqa: F401

    path = Path(mark)
    if not path.exists():
        path.write_text(repr(time.time()))
        os._exit(1)
    return time.time() - float(path.read_text())
