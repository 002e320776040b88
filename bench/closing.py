"""Closing: the fast path against the reference path on the same candidates.

    python bench/closing.py [--hand panda ...] [--object mug] [--approaches 24]

For each hand, the sweep's own candidates (surface rays, every preshape,
rolls and standoffs) are closed twice in one process: by
``Grasper(reference=True)`` (the plain implementation: PyBullet back-off,
speed bounds recomputed at every step) and by the default fast path.
Printed: CPU milliseconds per candidate of approach + closing + contact
reading (``time.process_time``: the machine is shared, wall time is not a
steady figure), PyBullet queries per candidate, and agreement: the same
outcome (closed, or the same rejection reason), closed joints within 0.01
rad or m and hand pose within 1 mm, and the same force-closure verdict.
"""

from __future__ import annotations

import os
import time

import numpy as np
from throughput import hand_parser

from planner.geometry.solid import load_object
from planner.plan import sampling
from planner.plan.closing import Closed, Grasper, Rejected
from planner.plan.sweep import SweepSettings, candidates, unit_rng
from planner.plan.unit import grasp_quality
from planner.sim import Sim
from planner.specs.hands import hand_names, load_hand
from planner.specs.preshapes import load_preshapes

#: Closed joints [rad or m] and hand position [m] this close count as the same grasp.
JOINT_TOL, POSITION_TOL = 0.01, 0.001


def close_all(hand, obj, todo, rays, radius, reference: bool):  # type: ignore[no-untyped-def]
    out, queries = [], 0
    with Sim() as sim:
        grasper = Grasper(sim, hand, sim.add_static_mesh(obj.mesh.vertices, obj.mesh.faces), reference=reference)
        t0 = time.process_time()
        for cand in todo:
            r = grasper.close(rays.points[cand.ray], rays.directions[cand.ray], cand.roll, cand.standoff,
                              cand.preshape, radius)
            queries += r.steps
            out.append(r)
        seconds = time.process_time() - t0
    return out, seconds, queries


def same(a: Closed | Rejected, b: Closed | Rejected) -> bool:
    if isinstance(a, Rejected) or isinstance(b, Rejected):
        return isinstance(a, Rejected) and isinstance(b, Rejected) and a.reason == b.reason
    dq = max(abs(a.closed_joints[k] - b.closed_joints[k]) for k in a.closed_joints)
    return dq < JOINT_TOL and float(np.linalg.norm(a.pose[:3, 3] - b.pose[:3, 3])) < POSITION_TOL


def force_closure(hand, obj, r: Closed | Rejected) -> bool | None:  # type: ignore[no-untyped-def]
    return grasp_quality(r.contacts, hand, obj, 8).force_closure if isinstance(r, Closed) else None


def main() -> None:
    args = hand_parser(__doc__).parse_args()
    obj = load_object(args.object)
    radius = obj.torque_scale + float(np.linalg.norm(obj.com))
    print(f"# closing on '{args.object}', {args.approaches} surface rays, load {os.getloadavg()[0]:.2f}")
    print("| hand | candidates | reference ms/cand | fast ms/cand | speed-up | queries/cand ref / fast | "
          "same outcome | same FC verdict |")
    print("|---|---:|---:|---:|---:|---|---:|---:|")
    for name in args.hand or hand_names():
        hand = load_hand(name)
        settings = SweepSettings(approaches=args.approaches, chunk=0, sampler="surface").resolved("surface")
        rays = sampling.sample(obj.mesh, sampler="surface", count=args.approaches,
                               rng=unit_rng(args.seed, obj.name, hand.name))
        todo = candidates(rays, load_preshapes(hand), settings, hand.roll_symmetry)
        ref, t_ref, q_ref = close_all(hand, obj, todo, rays, radius, True)
        fast, t_fast, q_fast = close_all(hand, obj, todo, rays, radius, False)

        n = len(todo)
        outcome = np.mean([same(a, b) for a, b in zip(ref, fast)])
        verdict = np.mean([force_closure(hand, obj, a) == force_closure(hand, obj, b) for a, b in zip(ref, fast)])
        print(f"| {name} | {n} | {1000 * t_ref / n:.2f} | {1000 * t_fast / n:.2f} | {t_ref / t_fast:.1f}x | "
              f"{q_ref / n:.1f} / {q_fast / n:.1f} | {100 * outcome:.1f}% | {100 * verdict:.1f}% |", flush=True)
    print(f"# load at end {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
