"""Candidates and force-closure grasps per second per core, with a per-stage breakdown.

    python bench/throughput.py [--object mug] [--hand panda ...] [--approaches 24]

Runs one unit per hand in this process (one core), writes it to a scratch
database, and prints figures for sampling, closing, contacts, quality and the
database write; then shake-tests a seeded uniform sample of the unit's grasps
(``--validate N``, default 40; 0 skips it) with the default trial, one world
per trial, and prints validated grasps per CPU second (the trial's own time:
the object's convex parts are prepared, and cached, before the clock starts).
"""

from __future__ import annotations

import argparse
import platform
import tempfile
import time
from pathlib import Path

import numpy as np

from planner.api import unit_row
from planner.db.store import open_db
from planner.plan.sweep import SweepSettings
from planner.plan.unit import UnitSpec, run_unit
from planner.specs.hands import hand_names, load_hand
from planner.validation.parts import trial_shape
from planner.validation.shake import ShakeSettings, trials

STAGES = ("prepare", "sampling", "rejection", "closing", "contacts", "quality", "reachability", "database")


def validated_rate(result, hand: str, count: int, seed: int) -> tuple[int, float]:  # type: ignore[no-untyped-def]
    """(grasps shake-tested, validated grasps per CPU second) on a seeded
    uniform sample of ``count`` of the unit's grasps."""
    grasps = sorted(result.grasps, key=lambda g: g.candidate)
    if count <= 0 or not grasps:
        return 0, float("nan")
    rng = np.random.default_rng(seed)
    picked = [grasps[i] for i in sorted(rng.choice(len(grasps), size=min(count, len(grasps)), replace=False))]
    settings = ShakeSettings()
    trial_shape(result.obj, settings.part_tolerance)  # CoACD parts: prepared (and cached) outside the clock
    t0 = time.process_time()
    trials(load_hand(hand), result.obj, picked, settings)
    return len(picked), len(picked) / (time.process_time() - t0)


def bench(obj: str, hand: str, approaches: int, seed: int, validate: int = 0) -> dict:
    settings = SweepSettings(approaches=approaches)
    t0 = time.perf_counter()
    result = run_unit(UnitSpec(obj, hand, settings, seed))
    total = time.perf_counter() - t0
    if result.error:
        raise SystemExit(f"{hand}: {result.error}")
    with tempfile.TemporaryDirectory() as tmp, open_db(Path(tmp) / "bench.db") as db:
        t1 = time.perf_counter()
        db.write_unit(unit_row(result, total), result.obj, result.grasps, db.rule())
        db_seconds = time.perf_counter() - t1
    timing = dict(result.timing, database=db_seconds)
    work = total + db_seconds
    return {"hand": hand, "candidates": result.candidates, "grasps": len(result.grasps),
            "fc": result.force_closure, "seconds": work, "rate": result.candidates / work,
            "fc_rate": result.force_closure / work, "timing": timing,
            "rejected": dict(result.rejected), "validated": validated_rate(result, hand, validate, seed)}


def hand_parser(doc: str | None) -> argparse.ArgumentParser:
    """The options the per-hand benchmarks share: object, hands, approaches, seed."""
    parser = argparse.ArgumentParser(description=doc)
    parser.add_argument("--object", default="mug")
    parser.add_argument("--hand", action="append", help="hand name (repeat); default: every hand")
    parser.add_argument("--approaches", type=int, default=24)
    parser.add_argument("--seed", type=int, default=0)
    return parser


def main() -> None:
    parser = hand_parser(__doc__)
    parser.add_argument("--validate", type=int, default=40, help="grasps to shake-test per hand (0: none)")
    args = parser.parse_args()
    print(f"# throughput on '{args.object}', {args.approaches} approaches, one process "
          f"({platform.processor() or platform.machine()}, Python {platform.python_version()})")
    print(f"{'hand':10s} {'cand':>6s} {'grasps':>6s} {'FC':>5s} {'cand/s/core':>11s} {'FC/s/core':>9s} "
          f"{'valid/s/core':>12s} | "
          "stage ms/candidate: " + " ".join(STAGES))
    for hand in args.hand or hand_names():
        r = bench(args.object, hand, args.approaches, args.seed, args.validate)
        per = {k: 1000 * v / max(r["candidates"], 1) for k, v in r["timing"].items()}
        print(f"{hand:10s} {r['candidates']:6d} {r['grasps']:6d} {r['fc']:5d} {r['rate']:11.1f} "
              f"{r['fc_rate']:9.2f} {r['validated'][1]:12.1f} | "
              + " ".join(f"{per.get(k, 0.0):.2f}" for k in STAGES)
              + f"   rejected: {r['rejected']}")


if __name__ == "__main__":
    main()
