"""The Barrett's settle: its cost and the ranking it gives, judged by the shake trial (issue 24, item 4).

    python bench/settle_rank.py [--objects duck teddy ...] [--rays 8] [--top 10] [--variant NAME ...] [--json FILE]

Per object (default: objects not looked at while choosing the settle, :data:`OBJECTS`), one unit of the Barrett's
default sweep without its settle (``--rays`` rays x 4 rolls x the preshapes, no reachability); then each settle
variant fills in the settled epsilons of those same grasps (CPU time measured), the grasps are ranked by the
ranking rule (:func:`ranked`: force closure as planned or once squeezed first, then score), and the union of every
variant's top ``--top`` is shake-tested once each with the default trial (``grasp validate``'s, one world per
grasp: a grasp gets the same verdict whichever variant ranked it). Printed per variant: settle CPU ms per
candidate, the share of the top-1 and of the top-10 that held (over objects), and how many of its top-10 are the
reference variant's.

Variants (:data:`VARIANTS`): ``all`` settles every grasp with the default trial's timing (main before issue
24); ``fc`` settles only the force-closure grasps (this branch's sweep: a grasp that is not force closure ranks
below every one that is, so its settled epsilon only orders it among those); ``fc_short`` settles only those,
with coarser, shorter dynamics.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from _trees import ROOT, uptime

sys.path.insert(0, str(ROOT))

#: Objects not used while choosing the settle (the mug and random_000..002 were).
OBJECTS = ("duck", "teddy", "bunny", "box", "cylinder", "random_010", "random_011", "random_012", "random_013",
           "random_014")


def variants() -> dict:
    from planner.validation.settings import ShakeSettings

    base = ShakeSettings(batch=1)
    return {"all": (False, base), "fc": (True, base),
            "fc_short": (True, replace(base, dt=1 / 240, close_time=0.12, settle_time=0.05))}


def ranked(grasps: list) -> list[int]:
    """Indices of ``grasps`` (Grasp records) best first, as the database ranks them: the grasps force closure as
    planned or once squeezed first (planner.db.ranking.FIRST), then by the default rule's score."""
    from planner.db.ranking import RankingRule, first_of, rank_order, rule_measures

    return [int(i) for i in rank_order(RankingRule().scores(rule_measures(grasps)), np.array(first_of(grasps)))]


def one_object(name: str, rays: int, top: int, chosen: list[str]) -> dict:
    from planner.geometry.solid import load_object
    from planner.plan.settle import with_settled
    from planner.plan.sweep import SweepSettings
    from planner.plan.unit import UnitSpec, run_unit
    from planner.specs.hands import load_hand
    from planner.validation.parts import trial_shape
    from planner.validation.shake import ShakeSettings, trials

    hand = load_hand("barrett")
    obj = load_object(name)
    trial_shape(obj, ShakeSettings().part_tolerance)
    unit = run_unit(UnitSpec(name, "barrett", SweepSettings(approaches=rays, chunk=0, reach_placements=0,
                                                            settle=False), 0))
    grasps = unit.grasps
    out: dict = {"candidates": unit.candidates, "grasps": len(grasps), "fc": unit.force_closure, "variants": {}}
    tops = {}
    for v in chosen:
        only_fc, settings = variants()[v]
        t = time.process_time()
        settled = with_settled(hand, obj, grasps, 8, settings, only_force_closure=only_fc)
        cpu = time.process_time() - t
        tops[v] = ranked(settled)[:top]
        out["variants"][v] = {"settle_cpu": cpu, "top": [grasps[i].candidate for i in tops[v]]}
    union = sorted({i for t in tops.values() for i in t})
    verdicts = dict(zip(union, trials(hand, obj, [grasps[i] for i in union], ShakeSettings())))
    for v in chosen:
        held = [bool(verdicts[i].success) for i in tops[v]]
        out["variants"][v].update(held=held, top1=held[0] if held else None)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--objects", nargs="+", default=list(OBJECTS))
    parser.add_argument("--rays", type=int, default=8)
    parser.add_argument("--top", type=int, default=10)
    parser.add_argument("--variant", action="append", help="default: all of them")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    from planner.threads import one_blas_thread

    chosen = args.variant or list(variants())
    print(f"# settle_rank: Barrett, {args.rays} rays per object, top {args.top}, variants {chosen}; "
          f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}")
    print(f"# {time.strftime('%Y-%m-%d %H:%M')} start: {uptime()}")
    results = {}
    with one_blas_thread():
        for name in args.objects:
            results[name] = r = one_object(name, args.rays, args.top, chosen)
            cells = "  ".join(f"{v}: {1000 * r['variants'][v]['settle_cpu'] / max(r['candidates'], 1):.1f} ms/cand "
                              f"top-1 {'held' if r['variants'][v]['top1'] else 'DROP'} "
                              f"top-{args.top} {sum(r['variants'][v]['held'])}/{len(r['variants'][v]['held'])}"
                              for v in chosen)
            print(f"{name:12s} cand {r['candidates']:4d} FC {r['fc']:4d}  {cells}", flush=True)
    print(f"# end: {uptime()}")
    ref = chosen[0]
    print(f"\n{'variant':10s} {'settle ms/cand':>15s} {'top-1 held':>11s} {'top-10 held':>12s} "
          f"{'top-10 = ' + ref:>16s}")
    for v in chosen:
        rows = [r["variants"][v] for r in results.values()]
        cand = sum(r["candidates"] for r in results.values())
        top1 = np.mean([bool(x["top1"]) for x in rows])
        top10 = np.mean([h for x in rows for h in x["held"]])
        same = np.mean([len(set(x["top"]) & set(r["variants"][ref]["top"])) / max(len(x["top"]), 1)
                        for x, r in zip(rows, results.values())])
        print(f"{v:10s} {1000 * sum(x['settle_cpu'] for x in rows) / cand:15.1f} {top1:11.2f} {top10:12.2f} "
              f"{same:16.2f}")
    if args.json:
        args.json.write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
