"""Reachable grasps on a table, before and after grasps planned on it.

Two modes.

``DB:OBJECT:HAND [...]``: why stored grasps are not reachable on a table:
the object in its most probable resting poses in front of the robot
(``grasp best --on-table``), the top ``--candidates`` grasps tried in query
order (grasps planned on the table in that pose first, then the rest), each
miss counted by reason (planner.plan.reach.MISSES). No planning on the spot.

``--build DIR --hands H,... --objects O,...``: for each hand and object, a
"before" database (the sweep on the object alone, ``SWEEP`` below) and an
"after" one (the same plus ``grasp generate --on-table``, the same sweep on
the table in the 3 most probable resting poses); then per resting pose:

- the share of the top ``--candidates`` grasps (query order) that the arm
  reaches with the hand off the table, before and after;
- the CPU time of ``best --object-pose POSE --top 1`` on each database (after:
  the stored table grasps; before: the stored grasps, then planning on the
  spot with the table when none is reachable) and where its grasp came from;
- the grasp that query returns: force closure, epsilon, weight it resists,
  settled epsilon, score, next to the best stored grasp of the object alone;
- the CPU time and the grasp of ``best --object-pose POSE --max-candidates 0``
  on the "before" database: planning on the spot with the table alone.

    python bench/reach_misses.py DB:OBJECT:HAND [...] [--candidates 100] [--poses 3]
    python bench/reach_misses.py --build DIR --hands panda,barrett --objects box,mug [--candidates 100]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import sqlite3
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

from planner import api

#: The sweep of both databases, per hand's sampler: a reduced default sweep.
SWEEP = {"antipodal": ["--approaches", "256"], "surface": ["--approaches", "16", "--rolls", "2"]}


def misses(cases: list[str], candidates: int, poses: int) -> None:
    for case in cases:
        db, obj, hand = case.split(":")
        start = time.process_time()
        tables = api.best_on_table(obj, hand, db_path=db, top=candidates, poses=poses, max_candidates=candidates,
                                   plan=False)
        for i, t in enumerate(tables):
            counted = Counter(why for _, why in t.misses)
            print(f"{obj}/{hand} resting pose {i + 1} (p={t.resting.probability:.2f}): "
                  f"{len(t.grasps)} of {len(t.grasps) + len(t.misses)} tried reachable; misses: "
                  + ("; ".join(f"{n} {why}" for why, n in counted.most_common()) or "none"))
        print(f"  ({time.process_time() - start:.1f} CPU s)")


def generate(db: Path, obj: str, hand: str, *extra: str) -> str:
    """Run ``grasp generate`` (one worker); a line of what it did and its CPU time."""
    sampler = api.hand(hand)[0].sampler
    cmd = [sys.executable, "-m", "planner.cli", "generate", obj, "--hand", hand, "--db", str(db), "--workers", "1",
           "--json", *SWEEP[sampler], *extra]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    out = subprocess.run(cmd, check=True, env=os.environ, capture_output=True, text=True).stdout
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
    summary = json.loads(out)
    return (f"{summary['candidates']} candidates, {summary['grasps']} grasps, {summary['force_closure']} force "
            f"closure, {cpu:.0f} CPU s")


def measures(g: api.Grasp) -> str:
    m = g.measures
    settled = "-" if m is None or m.settled_epsilon is None else f"{m.settled_epsilon:.3f}"
    resist = "-" if m is None else f"{m.resist_worst:.1f}"
    return f"fc {int(g.force_closure)}, eps {g.epsilon:.3f}, holds {resist} g, settled {settled}, score {g.score:.3f}"


def build(folder: Path, hands: list[str], objects: list[str], candidates: int) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    print("| hand | object | pose (p) | reachable of top before | after | query before: CPU s, from | "
          "query after: CPU s, from | grasp found (after) | planned on the spot: CPU s, grasp | "
          "best stored grasp, object alone |")
    print("|---|---|---|---:|---:|---|---|---|---|---|")
    for hand in hands:
        for obj in objects:
            name = Path(obj).stem
            before, after = folder / f"{hand}_{name}_before.db", folder / f"{hand}_{name}_after.db"
            if not before.exists():
                print(f"<!-- {hand} {name} object alone: {generate(before, obj, hand)} -->", flush=True)
            if not after.exists():
                with sqlite3.connect(before) as source, sqlite3.connect(after) as copy:
                    source.backup(copy)
                print(f"<!-- {hand} {name} on the table: {generate(after, obj, hand, '--on-table')} -->", flush=True)
            row = api.best(name, hand, db_path=before)[0]
            shares = [api.best_on_table(name, hand, db_path=db, top=candidates, max_candidates=candidates,
                                        plan=False) for db in (before, after)]
            for i, (b, a) in enumerate(zip(*shares)):
                pose = a.object_pose7()
                times, found = [], []
                for db in (before, after):
                    start = time.process_time()
                    r = api.best_at(name, hand, pose, db_path=db, top=1)
                    times.append(time.process_time() - start)
                    found.append(r[0] if r else None)
                where = ["none" if f is None else "planned now" if f.planned_now else
                         f"stored #{f.grasp.rank}" + (" (table)" if f.grasp.table_plane is not None else "")
                         for f in found]
                got = "-" if found[1] is None else measures(found[1].grasp)
                start = time.process_time()
                now = api.best_at(name, hand, pose, db_path=before, top=1, max_candidates=0)
                planned = f"{time.process_time() - start:.2f}, " + (measures(now[0].grasp) if now else "none")
                print(f"| {hand} | {name} | {i + 1} ({a.resting.probability:.2f}) | {len(b.grasps)}/{candidates} | "
                      f"{len(a.grasps)}/{candidates} | {times[0]:.2f}, {where[0]} | {times[1]:.2f}, {where[1]} | "
                      f"{got} | {planned} | {measures(row)} |", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("cases", nargs="*", metavar="DB:OBJECT:HAND")
    parser.add_argument("--candidates", type=int, default=100)
    parser.add_argument("--poses", type=int, default=3)
    parser.add_argument("--build", type=Path, metavar="DIR")
    parser.add_argument("--hands", default="panda,barrett,allegro,pr2")
    parser.add_argument("--objects", default="box,cylinder,mug,duck")
    args = parser.parse_args()
    if args.build:
        build(args.build, args.hands.split(","), args.objects.split(","), args.candidates)
    else:
        misses(args.cases, args.candidates, args.poses)


if __name__ == "__main__":
    main()
