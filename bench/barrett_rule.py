"""The formula's weights for a hand that settles (the Barrett), against the MuJoCo trial (issue 26 item 6).

The Barrett has no external labels, so no p_hold: its rank is the rule's formula, whose settled-epsilon term was
weighted 100 by a cross-validation against this project's PyBullet trial, the simulator that also makes the
settled epsilon. Here the formula's weights are chosen against the MuJoCo trial (another engine and protocol) on
random objects of their own, ``--objects`` (default random_300..323: none of bench/mujoco_protocols.py's 15, which
are left to check the choice): each is swept as mujoco_protocols sweeps the Barrett (24 approaches, 2 rolls, no
reachability) into ``--db-dir``; ``--sample`` force-closure grasps per object drawn uniformly are tried in both
engines (printed: each measure's mean per-object ROC AUC against MuJoCo's verdict and against "held in both");
then for each point of the grid (cap, eps_weight, settled_weight) the object's 10 best force-closure grasps under
that rule are tried (trials cached by grasp in ``DIR/trials.json``) and the share of top-1 and top-10 grasps held in
MuJoCo and in both engines printed, best first by their sum.

    python bench/barrett_rule.py [--db-dir /tmp/btune] [--objects random_300 ...] [--sample 60]
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
from pathlib import Path

import numpy as np

GRID = list(itertools.product((5.0, 20.0, 50.0), (0.1, 1.0, 3.0, 10.0), (0.0, 1.0, 3.0, 10.0, 30.0, 100.0)))
MEASURES = ("epsilon", "settled_epsilon", "resist_worst", "push", "open_margin")


def sweep(db: Path, objects: list[str]) -> None:
    from planner import api
    from planner.plan.sweep import SweepSettings

    if not db.exists():
        s = api.generate(objects, "barrett", db_path=db, workers=1,
                         settings=SweepSettings(approaches=24, rolls=2, reach_placements=0))
        print(f"{db.name}: {s.grasps} grasps, {s.force_closure} force closure", file=sys.stderr, flush=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--db-dir", type=Path, default=Path("/tmp/btune"))
    ap.add_argument("--objects", nargs="*", default=[f"random_{i}" for i in range(300, 324)])
    ap.add_argument("--sample", type=int, default=60)
    a = ap.parse_args()
    from planner.calibration.metrics import roc_auc
    from planner.db.objects import stored_object
    from planner.db.ranking import RankingRule, rank_order, rule_measures
    from planner.db.store import open_db
    from planner.specs.hands import load_hand
    from planner.validation import mujoco_trial, shake

    a.db_dir.mkdir(parents=True, exist_ok=True)
    db = a.db_dir / "barrett_rule.db"
    sweep(db, a.objects)
    hand = load_hand("barrett")
    cache_path = a.db_dir / "trials.json"
    cache = json.loads(cache_path.read_text()) if cache_path.exists() else {}
    objects = {}
    with open_db(db, create=False, readonly=True) as d:
        for o, h in d.pairs():
            grasps = [g for g in d.best(o, h, 10**9) if g.force_closure]
            if grasps:
                objects[o] = (grasps, stored_object(d.object_row(o)))

    def verdicts(name: str, grasps: list) -> np.ndarray:
        todo = [g for g in grasps if str(g.id) not in cache]
        for engine, key in ((mujoco_trial, "mujoco"), (shake, "pybullet")):
            for g, t in zip(todo, engine.trials(hand, objects[name][1], todo) if todo else []):
                cache.setdefault(str(g.id), {})[key] = int(t.success)
        if todo:
            cache_path.write_text(json.dumps(cache))
        return np.array([(cache[str(g.id)]["mujoco"], cache[str(g.id)]["pybullet"]) for g in grasps], float)

    rng = np.random.default_rng(0)
    mj, both, parts = [], [], {m: [] for m in MEASURES}
    for name, (grasps, _) in objects.items():
        picked = [grasps[i] for i in sorted(rng.choice(len(grasps), size=min(a.sample, len(grasps)), replace=False))]
        v = verdicts(name, picked)
        mj.append(v[:, 0])
        both.append(v[:, 0] * v[:, 1])
        m = rule_measures(picked)
        for k in MEASURES:
            parts[k].append(np.nan_to_num(m[k]))
    print(f"{sum(len(v) for v in mj)} uniformly sampled force-closure grasps of {len(objects)} objects: held in MuJoCo "
          f"{np.mean(np.concatenate(mj)):.3f}, in both {np.mean(np.concatenate(both)):.3f}")
    for k in MEASURES:
        print(f"  mean per-object AUC of {k:16s} MuJoCo {np.nanmean([roc_auc(y, x) for y, x in zip(mj, parts[k])]):.3f}"
              f"  both {np.nanmean([roc_auc(y, x) for y, x in zip(both, parts[k])]):.3f}")
    rows = []
    for cap, eps_weight, settled_weight in GRID:
        rule = RankingRule(cap=cap, eps_weight=eps_weight, settled_weight=settled_weight)
        tops = []
        for name, (grasps, _) in objects.items():
            order = rank_order(rule.scores(rule_measures(grasps)), np.ones(len(grasps)))[:10]
            v = verdicts(name, [grasps[i] for i in order])
            tops.append((v[0, 0], v[:, 0].mean(), v[0, 0] * v[0, 1], (v[:, 0] * v[:, 1]).mean()))
        rows.append((cap, eps_weight, settled_weight, *np.mean(tops, axis=0)))
    print("cap  eps_weight  settled_weight | top-1 MuJoCo  top-10 MuJoCo | top-1 both  top-10 both")
    for r in sorted(rows, key=lambda r: -sum(r[3:])):
        print(f"{r[0]:4.0f}  {r[1]:10.1f}  {r[2]:14.1f} | {r[3]:12.3f}  {r[4]:13.3f} | {r[5]:10.3f}  {r[6]:11.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
