"""Seconds per validated grasp, and the calibration run of the physical
validation: top-1 simulated success per object.

    python bench/validate.py --hand panda [--db out/calib_panda.db] [--top 10] [--robust 5]

Builds a database for 20 objects (mug, duck, teddy, bunny, box, cylinder,
sphere and random_000..012) unless it exists, validates each object's top
grasps (shake trial + robust epsilon), prints seconds per validated grasp and
the per-hand summary of ``grasp report``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from planner import api
from planner.plan.sweep import SweepSettings
from planner.present import report
from planner.validation.run import validate

OBJECTS = ["mug", "duck", "teddy", "bunny", "box", "cylinder", "sphere"] + [f"random_{i:03d}" for i in range(13)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--hand", default="panda")
    parser.add_argument("--db", type=Path)
    parser.add_argument("--approaches", type=int, default=48)
    parser.add_argument("--top", type=int, default=10)
    parser.add_argument("--robust", type=int, default=5)
    parser.add_argument("--workers", type=int, default=api.default_workers())
    args = parser.parse_args()
    db = args.db or Path("out") / f"calib_{args.hand}.db"
    db.parent.mkdir(parents=True, exist_ok=True)
    t = time.perf_counter()
    summary = api.generate(OBJECTS, args.hand, db_path=db, settings=SweepSettings(approaches=args.approaches),
                           workers=args.workers)
    print(f"generate: {summary.candidates} candidates, {summary.force_closure} force-closure, "
          f"{time.perf_counter() - t:.0f} s, failed: {summary.failed}")
    t = time.perf_counter()
    result = validate(db, top=args.top, robust_samples=args.robust, workers=args.workers)
    dt = time.perf_counter() - t
    print(f"validate: {result.grasps} grasps, {result.successes} held, {dt:.0f} s on {args.workers} workers = "
          f"{dt * args.workers / max(result.grasps, 1):.2f} s per validated grasp per core "
          f"(trial + {args.robust} robust samples); failed: {result.failed_tasks}")
    for rep in report.collect(db):
        for key, value in report._summary_rows(rep):
            print(f"  {rep.hand}: {key}: {value}")
        for row in report._per_object(rep):
            print("   ", " | ".join(row))


if __name__ == "__main__":
    main()
