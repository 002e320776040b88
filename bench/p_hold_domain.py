"""What p_hold's domain means: each object's grasps tried in MuJoCo at the object's own mass and friction, and at
the conditions of the labels the hand's p_hold model was fitted on (its domain's lowest density and friction: the
dev set's 150 kg/m^3 and 1.0 for the shipped Panda model), beside the grasps' mean p_hold.

    python bench/p_hold_domain.py --db grasps.db [--hand panda] [--per-object 100] [--seed 0] [--json-out FILE]

Per object of the database with force-closure grasps for the hand: a seeded uniform sample of ``--per-object`` of
them (all if fewer), each tried twice with ``planner.validation.mujoco_trial.trials`` at its default settings: at
the stored mass and friction, then at the labels' (mass = the domain's density x the object's volume). Prints one
row per object (density, whether the model calls it outside its domain, mean p_hold, held share at both) and the
totals. Nothing is written to the database.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

#: The columns after the object's density and whether it lies outside the model's domain.
HEAD = ("grasps", "p_hold", "stored", "labels")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--db", type=Path, required=True)
    parser.add_argument("--hand", default="panda")
    parser.add_argument("--per-object", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json-out", type=Path)
    args = parser.parse_args(argv)

    from planner.db.objects import stored_object
    from planner.db.store import open_db
    from planner.specs.hands import load_hand
    from planner.validation.mujoco_settings import MujocoSettings
    from planner.validation.mujoco_trial import trials

    hand = load_hand(args.hand)
    rows = []
    with open_db(args.db, create=False, readonly=True) as db:
        model = db.model(args.hand)
        if model is None or not model.domain:
            raise SystemExit(f"{args.db}: no p_hold model with a domain for the {args.hand}")
        density, friction = model.domain["density"][0], model.domain["friction"][0]
        print(f"labels' conditions: density {density:.1f} kg/m^3, friction {friction:g}")
        print(f"{'object':14s} {'kg/m^3':>8s} {'outside':>7s} " + " ".join(f"{h:>6s}" for h in HEAD))
        for name in sorted(db.objects_for(args.hand)):
            fc = [g for g in db.best(name, args.hand, 10**9, 0) if g.force_closure]
            if not fc:
                continue
            rng = np.random.default_rng(args.seed)
            picked = [fc[i] for i in sorted(rng.choice(len(fc), size=min(args.per_object, len(fc)), replace=False))]
            row = db.object_row(name)
            obj = stored_object(row)
            held = {}
            for tag, mass, mu in (("stored", obj.mass, obj.friction), ("labels", density * obj.volume, friction)):
                held[tag] = float(np.mean([t.success for t in trials(hand, obj, picked, MujocoSettings(), mu, mass)]))
            out = {"object": name, "density": obj.density, "mass": obj.mass, "friction": obj.friction,
                   "outside": model.outside(row.properties()), "grasps": len(picked),
                   "p_hold": float(np.mean([g.p_hold for g in picked])), **held}
            rows.append(out)
            print(f"{name:14s} {obj.density:8.0f} {'yes' if out['outside'] else 'no':>7s} {len(picked):6d} "
                  f"{out['p_hold']:6.3f} {held['stored']:6.3f} {held['labels']:6.3f}", flush=True)
    n = np.array([r["grasps"] for r in rows], float)
    if len(n):
        def mean(key: str) -> float:
            return float(np.array([r[key] for r in rows]) @ n / n.sum())

        print(f"{'all':14s} {'':8s} {'':7s} {int(n.sum()):6d} {mean('p_hold'):6.3f} {mean('stored'):6.3f} "
              f"{mean('labels'):6.3f}")
    if args.json_out:
        args.json_out.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
