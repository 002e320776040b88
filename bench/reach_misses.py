"""Why stored grasps are not reachable on a table: for each (database, object,
hand) given, the object in its most probable resting poses in front of the
robot (``grasp best --on-table``), the top ``--candidates`` grasps tried in
rank order, each miss counted by reason (planner.plan.reach.MISSES).

    python bench/reach_misses.py DB:OBJECT:HAND [...] [--candidates 100] [--poses 3]
"""

from __future__ import annotations

import argparse
import time
from collections import Counter

from planner import api


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("cases", nargs="+", metavar="DB:OBJECT:HAND")
    parser.add_argument("--candidates", type=int, default=100)
    parser.add_argument("--poses", type=int, default=3)
    args = parser.parse_args()
    for case in args.cases:
        db, obj, hand = case.split(":")
        start = time.process_time()
        tables = api.best_on_table(obj, hand, db_path=db, top=args.candidates, poses=args.poses,
                                   max_candidates=args.candidates)
        for i, t in enumerate(tables):
            misses = Counter(why for _, why in t.misses)
            print(f"{obj}/{hand} resting pose {i + 1} (p={t.resting.probability:.2f}): "
                  f"{len(t.grasps)} of {len(t.grasps) + len(t.misses)} tried reachable; misses: "
                  + ("; ".join(f"{n} {why}" for why, n in misses.most_common()) or "none"))
        print(f"  ({time.process_time() - start:.1f} CPU s)")


if __name__ == "__main__":
    main()
