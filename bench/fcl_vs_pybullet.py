"""python-fcl against PyBullet for the queries closing asks, on one hand and the exact object mesh.

    python bench/fcl_vs_pybullet.py [--hand panda] [--object mug] [--poses 300] [--seed 0]

Random hand poses (random orientation, fingers at random joint values)
whose palm lies within 12 cm of the object's centre; each pose is bucketed by
the true gap of the hand to the exact mesh (fcl distance). Per bucket, CPU
microseconds per query (``time.process_time``; the hand's placement
included for fcl, as the planner pays it), median over poses:

- overlap: PyBullet ``getClosestPoints`` with range 0 (every overlapping
  triangle pair) against python-fcl booleans per hand shape (early exit);
- gap: PyBullet within 10 mm, against fcl's exact distance (no range);

and the agreement of the overlap verdicts.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.spatial.transform import Rotation

from planner.geometry.solid import load_object
from planner.sim import Sim
from planner.sim import fcl as adapter
from planner.specs.hands import load_hand

#: Gap buckets [m]: overlapping, 0-2 mm, 2-10 mm, 1-3 cm, farther.
EDGES = (0.0, 0.002, 0.01, 0.03)
NAMES = ("overlapping", "0-2 mm", "2-10 mm", "1-3 cm", "> 3 cm")
REPEAT = 5


def cpu_us(fn) -> tuple[float, object]:  # type: ignore[no-untyped-def]
    t = time.process_time()
    for _ in range(REPEAT):
        out = fn()
    return 1e6 * (time.process_time() - t) / REPEAT, out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--hand", default="panda")
    parser.add_argument("--object", default="mug")
    parser.add_argument("--poses", type=int, default=300)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    hand, obj = load_hand(args.hand), load_object(args.object)
    rng = np.random.default_rng(args.seed)
    rows: dict[str, list[tuple[float, float, float, float, bool]]] = {n: [] for n in NAMES}
    with Sim() as sim:
        target = sim.add_static_mesh(obj.mesh.vertices, obj.mesh.faces)
        body = sim.load_urdf(hand.urdf)
        links = [n for n in hand.links if sim.has_collision(body, n)]
        shapes = adapter.LinkShapes(sim, body, hand.urdf, links)
        bvh = adapter.object_bvh(obj.mesh.vertices, obj.mesh.faces)
        offset = hand.distance_offset
        for k in range(args.poses):
            pose = np.eye(4)
            pose[:3, :3] = Rotation.random(random_state=args.seed * 100_003 + k).as_matrix()
            pose[:3, 3] = obj.com + rng.uniform(-0.12, 0.12, 3)
            sim.set_pose(body, pose)
            sim.set_joints(body, {j.name: rng.uniform(j.lower, j.upper) for j in hand.joints})
            shapes.update()
            gap = shapes.distance(bvh)
            bucket = NAMES[int(np.searchsorted(EDGES, gap, side="left"))] if gap > 0 else NAMES[0]
            pb_overlap, pb_pairs = cpu_us(lambda: sim.closest(body.uid, target, -offset))
            fcl_overlap, fcl_verdict = cpu_us(lambda: (shapes.update(), shapes.collides(bvh))[1])
            pb_gap, _ = cpu_us(lambda: sim.closest(body.uid, target, 0.01 - offset))
            fcl_gap, _ = cpu_us(lambda: (shapes.update(), shapes.distance(bvh))[1])
            same = bool(fcl_verdict) == (len(pb_pairs) > 0 and pb_pairs.min_distance + offset <= 0)  # type: ignore[attr-defined]
            rows[bucket].append((pb_overlap, fcl_overlap, pb_gap, fcl_gap, same))
    print(f"# {args.hand} on '{args.object}', {args.poses} poses, CPU us per query (median), "
          f"load {open('/proc/loadavg').read().split()[0]}")
    print("| gap bucket | poses | overlap: PyBullet range 0 | fcl booleans | gap: PyBullet 10 mm | fcl distance | "
          "same overlap verdict |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for name, r in rows.items():
        if not r:
            continue
        a = np.array(r, float)
        med = np.median(a[:, :4], axis=0)
        print(f"| {name} | {len(r)} | {med[0]:.0f} | {med[1]:.0f} | {med[2]:.0f} | {med[3]:.0f} | "
              f"{100 * a[:, 4].mean():.0f}% |")


if __name__ == "__main__":
    main()
