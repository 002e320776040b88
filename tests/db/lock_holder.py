"""``python lock_holder.py DB READY [plain|executor-fork|os-fork]``: take the
writer lock of DB, optionally start a forked child that never ends (as
``ProcessPoolExecutor`` did in issue 13; the child marks READY.child.<pid>),
mark READY, then wait until stdin closes."""

from __future__ import annotations

import multiprocessing
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from planner.db.lock import writer_lock
from tests.run import pool_units as units  # the repository is on PYTHONPATH (tests/processes.py)


def main() -> None:
    db, ready, mode = Path(sys.argv[1]), Path(sys.argv[2]), sys.argv[3]
    children = ready.with_name(ready.name + ".children")
    children.mkdir()
    with writer_lock(db):
        if mode == "executor-fork":
            pool = ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("fork"))
            pool.submit(units.block_forever, str(children))
        elif mode == "os-fork" and os.fork() == 0:
            units.block_forever(str(children))
        if mode != "plain":
            while not any(children.iterdir()):
                pass
        ready.touch()
        sys.stdin.read()
    os._exit(0)  # do not wait for a forked child


if __name__ == "__main__":
    main()
