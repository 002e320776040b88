"""Cost of the grip measures (planner.plan.grip) per closed grasp, CPU time.

For each hand and built-in object: a small sweep (``grasp generate`` with
``--approaches``), then every stored grasp is closed again at its pose
(``Grasper.close_at``) and its grip measured; prints the CPU ms per grasp of
the closing and of the grip measures, and the surface's one-time cost, beside
the last saved run (bench/grip.json; ``--save`` replaces it).

    python bench/grip.py [--hands panda barrett] [--objects mug box duck] [--approaches 64] [--save]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from planner import api
from planner.db.store import open_db
from planner.geometry.solid import load_object
from planner.plan import grip
from planner.plan.closing import Closed, Grasper
from planner.plan.sweep import SweepSettings
from planner.record.grasp import Grasp
from planner.sim import Sim
from planner.specs.hands import HandSpec, load_hand
from planner.specs.preshapes import Preshape, load_preshapes
from planner.threads import one_blas_thread


def timed(hand: HandSpec, shapes: dict[str, Preshape], name: str, grasps: list[Grasp]) -> dict:
    """CPU ms of object ``name``'s grip surface (once), and per grasp of closing at its pose and measuring its grip,
    with one BLAS thread as a unit of work runs (:func:`planner.threads.one_blas_thread`: with the second
    thread spinning on a loaded machine, the Barrett's grip measured more than it costs in a sweep)."""
    obj = load_object(name)
    closing = measuring = 0.0
    n = 0
    with one_blas_thread(), Sim() as sim:
        grasper = Grasper.for_object(sim, hand, obj)
        t0 = time.process_time()
        surface = grip.GripSurface(obj.mesh, normals_at=grasper.normals_at())  # as a unit makes it
        prepare = time.process_time() - t0
        for g in grasps:
            t0 = time.process_time()
            closed = grasper.close_at(np.asarray(g.pose, float), shapes[g.preshape])
            t1 = time.process_time()
            if not isinstance(closed, Closed):
                continue
            grip.measure(hand, surface, closed.contacts, closed.link_poses or {}, obj.com)
            t2 = time.process_time()
            closing += t1 - t0
            measuring += t2 - t1
            n += 1
    return {"hand": hand.name, "object": name, "grasps": n, "surface_ms": 1000 * prepare,
            "close_ms": 1000 * closing / max(n, 1), "grip_ms": 1000 * measuring / max(n, 1)}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--hands", nargs="*", default=["panda", "barrett"])
    parser.add_argument("--objects", nargs="*", default=["mug", "box", "duck"])
    parser.add_argument("--approaches", type=int, default=64)
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--save", action="store_true", help="write this run to bench/grip.json")
    args = parser.parse_args()
    saved = Path(__file__).with_name("grip.json")
    before = {(r["hand"], r["object"]): r for r in json.loads(saved.read_text())} if saved.exists() else {}
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        db = Path(tmp) / "g.db"
        for hand_name in args.hands:
            settings = SweepSettings(approaches=args.approaches, reach_placements=0)
            api.generate(args.objects, hand_name, db_path=db, settings=settings, workers=1)
            hand = load_hand(hand_name)
            shapes = {s.name: s for s in load_preshapes(hand)}
            for name in args.objects:
                with open_db(db, create=False, readonly=True) as d:
                    grasps = d.best(name, hand_name, 100_000)
                rows.append(timed(hand, shapes, name, grasps))
    if args.json:
        print(json.dumps(rows, indent=1))
    else:
        print(f"{'hand':8s} {'object':8s} {'grasps':>7s} {'surface ms (once)':>18s} {'closing ms':>11s} "
              f"{'grip ms':>8s} {'grip ms (saved run)':>20s}")
        for r in rows:
            old = before.get((r["hand"], r["object"]))
            print(f"{r['hand']:8s} {r['object']:8s} {r['grasps']:7d} {r['surface_ms']:18.1f} {r['close_ms']:11.2f} "
                  f"{r['grip_ms']:8.2f} {old['grip_ms'] if old else float('nan'):20.2f}")
    if args.save:
        saved.write_text(json.dumps(rows, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
