"""How soon ``grasp generate``'s progress bar can show an ETA.

    python bench/progress.py [OBJECT ...] [--hand barrett] [--workers 2] [--approaches N]

Runs ``api.generate`` into a fresh database with a recording progress
callback and prints, in seconds from the start of the call:

- first count: the first report of a candidate count above zero (with a
  known total), i.e. the moment a candidate-level bar first moves;
- ETA: the second such report with a larger count (rich's
  ``TimeRemainingColumn`` needs two points to estimate a speed), the moment
  the bar's ``ETA -:--:--`` turns into a time;
- first unit: the first finished unit, when a unit-level bar (the one before)
  first moved, and its ETA the second finished unit;
- end, the number of callbacks, and whether the candidate count only went up
  and ended at the total.

One process, one run; the figures depend on the machine's load.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from planner import api  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("objects", nargs="*", default=["box"])
    ap.add_argument("--hand", default="barrett")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--approaches", type=int)
    args = ap.parse_args()
    calls: list[tuple[float, api.GenerateProgress]] = []
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        summary = api.generate(args.objects, args.hand, db_path=Path(tmp) / "p.db", workers=args.workers,
                               settings=api.SweepSettings(approaches=args.approaches),
                               progress=lambda p: calls.append((time.perf_counter() - start, p)))
        end = time.perf_counter() - start
    moving = [(t, p) for t, p in calls if p.candidates_done > 0 and p.candidates_total is not None]
    eta = next((t for t, p in moving if p.candidates_done > moving[0][1].candidates_done), None) if moving else None
    units = [t for t, p in calls if p.result is not None]
    done = [p.candidates_done for _, p in calls]
    last = calls[-1][1]
    print(f"{' '.join(args.objects)} / {args.hand}, {args.workers} workers: {summary.units} units, "
          f"{summary.candidates} candidates tried, {last.candidates_total} planned")
    print(f"first count {moving[0][0]:.1f} s, ETA {eta:.1f} s" if moving and eta else "no candidate count moved")
    print(f"first unit {units[0]:.1f} s, second unit {units[1]:.1f} s" if len(units) > 1 else
          f"units finished at {', '.join(f'{t:.1f}' for t in units)} s")
    print(f"end {end:.1f} s, {len(calls)} callbacks, monotone {done == sorted(done)}, "
          f"ends at total {last.candidates_done == last.candidates_total}")


if __name__ == "__main__":
    main()
