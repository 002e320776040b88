"""Batch scaling: objects/hour and grasps/second for 1 and 2 local workers
and for a local Ray instance, on the same object set, and the time a
1,000-object run would take.

    python bench/batch.py [--objects 20] [--approaches 16]

Each configuration builds its own database from scratch (same seed), so the
three runs do identical work; the script also checks they store identical
grasps.
"""

from __future__ import annotations

import argparse
import os
import sqlite3
import tempfile
import time
from pathlib import Path

from planner import api
from planner.plan.sweep import SweepSettings


def content(db: Path) -> list[tuple]:
    with sqlite3.connect(db) as conn:
        return conn.execute("SELECT object, candidate, pose, epsilon, score FROM grasps ORDER BY object, candidate"
                            ).fetchall()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--objects", type=int, default=20)
    parser.add_argument("--approaches", type=int, default=16)
    parser.add_argument("--hand", default="panda")
    args = parser.parse_args()
    names = [f"builtin:random:{args.objects}"]
    settings = SweepSettings(approaches=args.approaches, chunk=0)  # one unit per object
    runs = [("1 worker", dict(workers=1)), ("2 workers", dict(workers=2)),
            ("Ray local, 2 CPUs", dict(workers=2, use_ray=True))]
    print(f"# {args.objects} objects from builtin:random, hand {args.hand}, {args.approaches} approaches, "
          f"{os.cpu_count()} cores")
    print(f"{'backend':20s} {'seconds':>8s} {'objects/h':>10s} {'grasps/s':>9s} {'cand/s':>8s} {'efficiency':>10s}")
    base, reference, two = None, None, 0.0
    for label, kwargs in runs:
        with tempfile.TemporaryDirectory() as tmp:
            db = Path(tmp) / "b.db"
            t = time.perf_counter()
            summary = api.generate(names, args.hand, db_path=db, settings=settings, seed=0, **kwargs)
            dt = time.perf_counter() - t
            got = content(db)
        reference = reference or got
        base = base or dt
        workers = kwargs["workers"]
        print(f"{label:20s} {dt:8.1f} {3600 * args.objects / dt:10.0f} {summary.grasps / dt:9.1f} "
              f"{summary.candidates / dt:8.1f} {base / (dt * workers):10.0%}"
              f"{'' if got == reference else '  (DIFFERENT RESULT!)'}")
        if label == "2 workers":
            two = dt
    print(f"extrapolated 1,000 objects at the 2-worker rate: {1000 * two / args.objects / 3600:.2f} h on this machine")


if __name__ == "__main__":
    main()
