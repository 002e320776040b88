"""A driver process for the kill tests: ``python pool_driver.py PROGRESS
--workers N --start-method M --moment busy|idle [--no-pdeathsig] [--lock DB]``.

busy: every worker runs a unit that never finishes (each marks PROGRESS/<pid>).
idle: the driver takes one result, writes PROGRESS/suspended and then
blocks in its own code, its workers idle. Either way it waits to be killed.
"""

from __future__ import annotations

import argparse
import time
from contextlib import nullcontext
from pathlib import Path

from planner.db.lock import writer_lock
from planner.run import pool
from tests.run import pool_units as units  # the repository is on PYTHONPATH (tests/processes.py)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("progress", type=Path)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--start-method", default=pool.START_METHOD)
    ap.add_argument("--moment", choices=["busy", "idle"], default="busy")
    ap.add_argument("--no-pdeathsig", action="store_true")
    ap.add_argument("--lock", type=Path)
    args = ap.parse_args()
    pool.USE_PDEATHSIG = not args.no_pdeathsig
    with writer_lock(args.lock) if args.lock else nullcontext():
        if args.moment == "busy":
            for _ in pool.run(units.block_forever, [str(args.progress)] * args.workers, args.workers,
                              start_method=args.start_method):
                pass
        else:
            for _ in pool.run(units.square, range(4 * args.workers), args.workers, start_method=args.start_method):
                (args.progress / "suspended").touch()
                while True:
                    time.sleep(3600)


if __name__ == "__main__":
    main()
