"""Seconds per validated grasp per core: the shake trial on the mug and a few
tuning objects (never held-out ones: bench/calibration_split.toml), for the
Panda and the Barrett; one world per trial and batched, against a fine
reference (time step and solver convergence) and against the trial before
issue 15 (run from a checkout of that code).

    python bench/validate.py [--hand panda barrett] [--per-object 12] [--batch 8]
        [--reference] [--old-tree DIR]

Builds one database per hand in ``out/`` unless it exists (a small sweep of
the objects, no reachability), samples each object's grasps uniformly (every
grasp with contacts, force closure or not; seed 20261123), runs one trial per
object first to fill the caches (convex parts, URDFs), then times every trial
in CPU seconds of this process (``time.process_time``: other jobs on the
shared machine inflate wall time far more). ``--old-tree DIR``: DIR holds
the code before issue 15 (``git archive <commit> | tar -x -C DIR``); its
trial runs in a subprocess on the same grasps.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import tomllib

OBJECTS = ("mug", "box", "sphere", "teddy", "random_002", "random_005")
SEED = 20261123
#: A finer trial: half the time step, twice the iterations, gentler and longer loads.
REFERENCE = {"dt": 1 / 960, "solver_iterations": 100, "ramp_time": 0.05, "hold_time": 0.3}
SPLIT = Path(__file__).with_name("calibration_split.toml")


def tuning_only(names: tuple[str, ...]) -> None:
    split = tomllib.loads(SPLIT.read_text())
    bad = [n for n in names if n not in split["tuning"] or n in split["held_out"]]
    if bad:
        raise SystemExit(f"not tuning objects (see {SPLIT}): {', '.join(bad)}")


def database(hand: str, approaches: int) -> Path:
    from planner import api
    from planner.plan.sweep import SweepSettings

    db = Path("out") / f"validate_{hand}.db"
    db.parent.mkdir(exist_ok=True)
    if not db.exists():
        t = time.perf_counter()
        s = api.generate(list(OBJECTS), hand, db_path=db, workers=1,
                         settings=SweepSettings(approaches=approaches, reach_placements=0))
        print(f"{hand}: generated {s.grasps} grasps ({s.force_closure} force closure) in "
              f"{time.perf_counter() - t:.0f} s", flush=True)
    return db


def sample(db: Path, hand: str, per_object: int) -> dict[str, list]:
    from planner.db.store import open_db
    from planner.validation.run import Selection

    with open_db(db, create=False, readonly=True) as handle:
        return {o: Selection(sample=per_object).pick(handle, o, hand, SEED) for o in OBJECTS}


def timed(run, grasps_by_object: dict[str, list]) -> tuple[list, float, float]:  # type: ignore[no-untyped-def]
    """(results in order, CPU s, wall s) of ``run(obj_name, grasps)`` over the objects, caches warmed first."""
    out, cpu, wall = [], 0.0, 0.0
    for name, grasps in grasps_by_object.items():
        run(name, grasps[:1])
        c, w = time.process_time(), time.perf_counter()
        out += run(name, grasps)
        cpu += time.process_time() - c
        wall += time.perf_counter() - w
    return out, cpu, wall


def new_trials(hand_name: str, settings):  # type: ignore[no-untyped-def]
    from planner.geometry.solid import load_object
    from planner.specs.hands import load_hand
    from planner.validation.shake import trials

    hand = load_hand(hand_name)
    return lambda name, grasps: trials(hand, load_object(name), grasps, settings)


def old_trials(tree: Path, hand: str, grasps_by_object: dict[str, list]) -> tuple[list[bool], float, float]:
    """The old trial on the same grasps, in a subprocess importing ``tree``'s planner."""
    payload = {o: [g.to_json() for g in gs] for o, gs in grasps_by_object.items()}
    path = Path("out") / f"validate_{hand}_grasps.json"
    path.write_text(json.dumps({"hand": hand, "grasps": payload}))
    env = dict(os.environ, PYTHONPATH=str(tree))
    done = subprocess.run([sys.executable, __file__, "--old-worker", str(path)], env=env, check=True,
                          capture_output=True, text=True)
    result = json.loads(done.stdout.strip().splitlines()[-1])
    return result["success"], result["cpu"], result["wall"]


def old_worker(path: Path) -> None:
    """Run in the old tree: rebuild the grasps from ``grasp best --json`` records and time its trial."""
    from planner.geometry.solid import load_object
    from planner.record.contacts import HandContacts
    from planner.record.grasp import Grasp
    from planner.specs.hands import load_hand
    from planner.validation.shake import trial

    data = json.loads(path.read_text())
    hand = load_hand(data["hand"])

    def grasp(d: dict) -> Grasp:
        c = d["contacts"]
        contacts = HandContacts(np.array([x["point"] for x in c], float).reshape(-1, 3),
                                np.array([x["normal"] for x in c], float).reshape(-1, 3), tuple(x["link"] for x in c))
        return Grasp(object=d["object"], hand=d["hand"], preshape=d["preshape"], candidate=d["candidate"],
                     seed=d["seed"], approach_point=np.zeros(3), approach_dir=np.array([0.0, 0.0, 1.0]), roll=0.0,
                     standoff=0.0, pose=np.array(d["pose"]), open_joints=d["open_joints"], closed_joints=d["joints"],
                     width=d["width"], contacts=contacts, epsilon=d["epsilon"], volume=d["volume"],
                     force_closure=d["force_closure"])

    grasps = {o: [grasp(d) for d in gs] for o, gs in data["grasps"].items()}
    results, cpu, wall = timed(lambda name, gs: [trial(hand, load_object(name), g) for g in gs], grasps)
    print(json.dumps({"success": [bool(r.success) for r in results], "cpu": cpu, "wall": wall}))


def per_grasp(seconds: float, n: int) -> str:
    return f"{1000 * seconds / max(n, 1):.0f}"


def bench_hand(hand: str, args: argparse.Namespace) -> None:
    from planner.validation.shake import ShakeSettings

    picked = sample(database(hand, args.approaches), hand, args.per_object)
    n = sum(map(len, picked.values()))
    load = os.getloadavg()[0]
    base, base_cpu, base_wall = timed(new_trials(hand, ShakeSettings()), picked)
    reasons: dict[str, int] = {}
    for r in base:
        reasons[r.reason] = reasons.get(r.reason, 0) + 1
    rows = [("new, one world per trial", sum(r.success for r in base), "1.000", "-", per_grasp(base_cpu, n),
             per_grasp(base_wall, n))]
    batched, cpu, wall = timed(new_trials(hand, ShakeSettings(batch=args.batch)), picked)
    rows.append((f"new, {args.batch} trials per world", sum(r.success for r in batched),
                 f"{np.mean([a.success == b.success for a, b in zip(base, batched)]):.3f}",
                 f"{sum(a == b for a, b in zip(base, batched))}/{n}", per_grasp(cpu, n), per_grasp(wall, n)))
    if args.reference:
        fine, cpu, wall = timed(new_trials(hand, replace(ShakeSettings(), **REFERENCE)), picked)
        rows.append(("reference (dt 1/960, 100 it, hold 0.3 s)", sum(r.success for r in fine),
                     f"{np.mean([a.success == b.success for a, b in zip(base, fine)]):.3f}", "-", per_grasp(cpu, n),
                     per_grasp(wall, n)))
    if args.old_tree:
        old, cpu, wall = old_trials(args.old_tree, hand, picked)
        rows.append(("old trial (before issue 15)", sum(old),
                     f"{np.mean([a.success == b for a, b in zip(base, old)]):.3f}", "-", per_grasp(cpu, n),
                     per_grasp(wall, n)))
    print(f"\n{hand}: {n} grasps ({args.per_object} per object, uniform over each object's grasps) of "
          f"{', '.join(OBJECTS)}; load average {load:.1f} -> {os.getloadavg()[0]:.1f}")
    print(f"reasons (new, one world per trial): {dict(sorted(reasons.items()))}")
    print("| trial | held | same verdict as new | bit-identical | CPU ms/grasp | wall ms/grasp |")
    print("|---|---:|---:|---:|---:|---:|")
    for row in rows:
        print("| " + " | ".join(map(str, row)) + " |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--hand", nargs="+", default=["panda", "barrett"])
    parser.add_argument("--per-object", type=int, default=12)
    parser.add_argument("--approaches", type=int, default=12, help="sweep of a new database")
    parser.add_argument("--batch", type=int, default=8, help="trials per world of the batched run")
    parser.add_argument("--reference", action="store_true", help="also the fine reference trial")
    parser.add_argument("--old-tree", type=Path, help="a checkout of the code before issue 15")
    parser.add_argument("--old-worker", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.old_worker:
        return old_worker(args.old_worker)
    tuning_only(OBJECTS)
    for hand in args.hand:
        bench_hand(hand, args)


if __name__ == "__main__":
    main()
