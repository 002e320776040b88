"""Reachability timings.

    python bench/reach.py [--grasps 50000]

1. IK + collision checks per grasp: every force-closure grasp of a real mug
   run (Panda), checked at one object pose; seconds per grasp check.
2. A ``best --object-pose`` query on a database of N grasps: the real run's
   rows are replicated (fresh candidate numbers, re-ranked) up to N, then
   ``planner.api.best_at`` is timed in-process (the interpreter start-up and
   imports are not counted; they are reported separately).
"""

from __future__ import annotations

import argparse
import sqlite3
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from planner import api
from planner.db.store import open_db
from planner.geometry.frames import pose_from_xyzquat
from planner.geometry.solid import load_object
from planner.plan.reach import ReachScene
from planner.plan.sweep import SweepSettings
from planner.sim import Sim
from planner.specs.hands import load_hand

POSE = (0.5, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--grasps", type=int, default=50_000)
    parser.add_argument("--approaches", type=int, default=64)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        db = Path(tmp) / "reach.db"
        api.generate(["mug"], "panda", db_path=db, settings=SweepSettings(approaches=args.approaches,
                                                                          reach_placements=0), workers=1)
        conn = sqlite3.connect(db)
        rows = conn.execute("SELECT pose, closed_joints, open_joints FROM grasps WHERE force_closure = 1").fetchall()
        import json

        obj, hand = load_object("mug"), load_hand("panda")
        with Sim() as sim:
            scene = ReachScene(sim, hand, obj)
            scene.place_object(pose_from_xyzquat(POSE))
            rng = np.random.default_rng(0)
            t = time.perf_counter()
            reached = 0
            for pose, closed, open_ in rows:
                r = scene.check(np.array(json.loads(pose)).reshape(4, 4), json.loads(closed), json.loads(open_), rng)
                reached += r.reachable
            per = (time.perf_counter() - t) / max(len(rows), 1)
        print(f"IK + collision checks: {per * 1000:.1f} ms per grasp (grasp and pre-grasp, "
              f"{len(rows)} force-closure grasps, {reached} reachable at {POSE[:3]})")
        n0 = conn.execute("SELECT COUNT(*) FROM grasps").fetchone()[0]
        copies = max(1, -(-args.grasps // n0))
        cols = [r[1] for r in conn.execute("PRAGMA table_info(grasps)") if r[1] not in ("id", "candidate", "rank")]
        for k in range(1, copies):
            conn.execute(f"INSERT INTO grasps ({', '.join(cols)}, candidate) SELECT {', '.join(cols)}, "
                         f"candidate + {k * 1_000_000} FROM grasps WHERE candidate < 1000000")
        conn.execute("DELETE FROM grasps WHERE id > ?", (args.grasps,))
        conn.commit()
        total = conn.execute("SELECT COUNT(*) FROM grasps").fetchone()[0]
        conn.close()
        with open_db(db) as handle:  # rank the copies as the database would
            handle.apply_rule(handle.rule(), force=True)
        for attempt in range(3):
            t = time.perf_counter()
            found = api.best_at("mug", "panda", POSE, db_path=db, top=1)
            dt = time.perf_counter() - t
            print(f"best --object-pose on {total} grasps: {dt * 1000:.0f} ms in-process "
                  f"(found {len(found)}, rank {found[0].grasp.rank if found else '-'}; run {attempt + 1})")
        t = time.perf_counter()
        subprocess.run([sys.executable, "-m", "planner.cli", "best", "mug", "--hand", "panda", "--db", str(db),
                        "--object-pose", ",".join(map(str, POSE)), "--json"], check=True, capture_output=True)
        print(f"the same as a CLI command, interpreter start-up included: {time.perf_counter() - t:.2f} s")


if __name__ == "__main__":
    main()
