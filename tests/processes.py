"""Waiting on what other processes bring about, and process trees: the
tests drive every moment by observed progress (files, database rows), never
by wall time; the bounds below are only how long to wait before failing."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

from planner.run import procs

TESTS = Path(__file__).resolve().parent
ROOT = TESTS.parent
#: [s] bound for "happens within seconds" (processes gone after a kill).
SOON = 10.0
#: [s] bound for a process to start and make progress (Python start-up, imports, Ray).
STARTUP = 180.0
#: [s] between looks.
POLL = 0.02


def wait_until(condition: Callable[[], bool], within: float, what: str) -> float:
    """Poll ``condition`` until true; return the seconds it took."""
    start = time.monotonic()
    while not condition():
        if time.monotonic() - start > within:
            raise AssertionError(f"not within {within:g} s: {what}")
        time.sleep(POLL)
    return time.monotonic() - start


def env() -> dict[str, str]:
    """This environment, with the repository and tests/ importable (workers import test units)."""
    path = os.pathsep.join(filter(None, [str(ROOT), str(TESTS), os.environ.get("PYTHONPATH")]))
    return {**os.environ, "PYTHONPATH": path}


def python(*args: str, **kwargs) -> subprocess.Popen:  # type: ignore[no-untyped-def]
    return subprocess.Popen([sys.executable, *args], env=env(), **kwargs)


def tree(pid: int) -> dict[int, int | None]:
    """Every process below ``pid``, with its start time (pid reuse proof)."""
    return {p: procs.start_ticks(p) for p in procs.descendants(pid)}


def running(processes: dict[int, int | None]) -> dict[int, int | None]:
    """Those still running (a zombie holds nothing and counts as gone)."""
    return {p: t for p, t in processes.items() if procs.alive(p, t)}


def kill_all(processes: dict[int, int | None]) -> None:
    """Clean up after a failed test: only the processes it started."""
    for p in running(processes):
        try:
            os.kill(p, signal.SIGKILL)
        except ProcessLookupError:
            pass


class Driver:
    """A driver process under test: ``with Driver(*argv) as d:``,
    ``d.snapshot()`` once it has made progress, ``d.kill()`` SIGKILLs it and
    returns the seconds until every snapshotted process is gone. On exit it
    and whatever is left of its tree are killed."""

    def __init__(self, *args: str, **kwargs) -> None:  # type: ignore[no-untyped-def]
        self.proc = python(*args, **kwargs)
        self.tree: dict[int, int | None] = {}

    def snapshot(self) -> dict[int, int | None]:
        self.tree = tree(self.proc.pid)
        return self.tree

    def kill(self) -> float:
        self.proc.send_signal(signal.SIGKILL)
        self.proc.wait()
        return wait_until(lambda: not running(self.tree), SOON,
                          f"processes of the killed driver gone: {running(self.tree)}")

    def __enter__(self) -> Driver:
        return self

    def __exit__(self, *exc: object) -> None:
        self.proc.kill()
        self.proc.wait()
        kill_all(self.tree)
