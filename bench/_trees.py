"""Helpers of the before/after benchmarks (``bench/yield_speed.py``, ``bench/throughput.py``).

An earlier commit is unpacked with ``git archive`` into a temporary folder;
each side then runs in its own child process with that tree first on
``PYTHONPATH``. The children switch the planner's stage timers to CPU time
(:func:`cpu_clocks`); the parent prints the load average at start and end
(:func:`uptime`), the machine may be shared.
"""

from __future__ import annotations

import importlib
import os
import subprocess
import sys
import tarfile
import time
import types
from pathlib import Path

#: The checkout these scripts belong to (the "after" tree).
ROOT = Path(__file__).resolve().parents[1]

#: Modules whose stage timers (``time.perf_counter``) :func:`cpu_clocks` switches to CPU time, where a tree has them.
TIMED = ("planner.plan.unit", "planner.plan.closing", "planner.plan.settle", "planner.plan.contacts",
         "planner.plan.reach", "planner.plan.sampling", "planner.plan.measures", "planner.plan.sweep")


def unpack(commit: str, into: Path) -> Path:
    """``git archive`` of ``commit`` extracted into ``into/before``; returns that folder."""
    archive = into / "before.tar"
    with archive.open("wb") as f:
        subprocess.run(["git", "-C", str(ROOT), "archive", commit], stdout=f, check=True)
    tree = into / "before"
    with tarfile.open(archive) as tar:
        tar.extractall(tree, filter="data")
    return tree


def uptime() -> str:
    """The ``uptime`` line (load average)."""
    return os.popen("uptime").read().strip()


def cpu_clocks() -> list[str]:
    """Make the planner's stage timers read CPU time of this process.

    Every module of :data:`TIMED` the tree has, and every other loaded
    ``planner.plan`` module, that uses ``time`` (``import time``) gets a
    copy of the ``time`` module whose ``perf_counter`` is ``process_time``;
    a module that did ``from time import perf_counter`` gets ``process_time``
    under that name. Returns the modules switched.
    """
    for name in TIMED:
        try:
            importlib.import_module(name)
        except ImportError:  # not in this tree
            pass
    clock = types.SimpleNamespace(**{k: getattr(time, k) for k in dir(time) if not k.startswith("__")})
    clock.perf_counter = time.process_time
    switched = []
    for name, module in sorted(sys.modules.items()):
        if not (name in TIMED or name.startswith("planner.plan.")) or module is None:
            continue
        if getattr(module, "time", None) is time:
            module.time = clock  # type: ignore[attr-defined]
            switched.append(name)
        elif getattr(module, "perf_counter", None) is time.perf_counter:
            module.perf_counter = time.process_time  # type: ignore[attr-defined]
            switched.append(name)
    return switched
