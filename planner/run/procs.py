"""Facts about processes, read from ``/proc`` (Linux), and the two Linux
process-lifetime switches (``prctl``) the pool and the Ray launcher use.

Elsewhere the readers return ``None`` / empty results and the switches
report that they are unavailable, so callers fall back to portable means.
"""

from __future__ import annotations

import ctypes
import os
import signal
import sys
from pathlib import Path

PROC = Path("/proc")
PR_SET_PDEATHSIG = 1  # <linux/prctl.h>
PR_SET_NAME = 15  # <linux/prctl.h>: the thread's name, /proc/<pid>/comm for the main thread
PR_SET_CHILD_SUBREAPER = 36  # <linux/prctl.h>, Linux >= 3.4


def _stat_fields(pid: int) -> list[str] | None:
    """Fields of ``/proc/<pid>/stat`` after the command name (field 3 on),
    or None if there is no such process (or no /proc)."""
    try:
        text = (PROC / str(pid) / "stat").read_text()
    except OSError:
        return None
    return text.rsplit(")", 1)[1].split()  # the name may hold spaces and ')'


def start_ticks(pid: int) -> int | None:
    """When ``pid`` started, in clock ticks since boot: with the pid, a
    process identity that survives pid reuse. None if unknown."""
    fields = _stat_fields(pid)
    return int(fields[19]) if fields else None


def alive(pid: int, ticks: int | None = None) -> bool:
    """Whether ``pid`` runs (a zombie does not), and, if ``ticks`` is given,
    is the same process that started then."""
    fields = _stat_fields(pid)
    if fields is None:
        if sys.platform.startswith("linux"):
            return False
        try:  # no /proc: existence only
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        except PermissionError:
            return True
        return True
    return fields[0] not in ("Z", "X") and (ticks is None or int(fields[19]) == ticks)


def parents() -> dict[int, int]:
    """pid -> parent pid of every running (not zombie) process."""
    out = {}
    for entry in PROC.iterdir() if PROC.is_dir() else ():
        if entry.name.isdigit():
            fields = _stat_fields(int(entry.name))
            if fields and fields[0] not in ("Z", "X"):
                out[int(entry.name)] = int(fields[1])
    return out


def descendants(pid: int) -> set[int]:
    """Running processes below ``pid`` in the process tree (not ``pid``)."""
    children: dict[int, list[int]] = {}
    for child, parent in parents().items():
        children.setdefault(parent, []).append(child)
    found, todo = set(), [pid]
    while todo:
        for child in children.get(todo.pop(), []):
            if child not in found:
                found.add(child)
                todo.append(child)
    return found


def _prctl(option: int, value: int | bytes) -> bool:
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        arg = ctypes.c_char_p(value) if isinstance(value, bytes) else ctypes.c_ulong(value)
        return libc.prctl(option, arg, 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


def set_name(name: str) -> bool:
    """Name this process for ``ps`` and ``top`` (Linux: at most 15 bytes,
    called from the main thread)."""
    return _prctl(PR_SET_NAME, name.encode()[:15])


def die_with_parent() -> bool:
    """Ask the kernel to SIGKILL this process when the *thread* that created
    it exits (Linux ``PR_SET_PDEATHSIG``). False where unavailable."""
    return _prctl(PR_SET_PDEATHSIG, signal.SIGKILL)


def adopt_orphans() -> bool:
    """Become the reaper of orphaned descendants (Linux
    ``PR_SET_CHILD_SUBREAPER``), so the whole tree stays below us."""
    return _prctl(PR_SET_CHILD_SUBREAPER, 1)
