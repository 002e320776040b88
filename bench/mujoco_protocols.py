"""Two independent dynamic protocols on the planner's own grasps (issue 26 item 6, issue 24 item 3):
PyBullet's shake trial and the MuJoCo trial on each object's best grasps, Panda and Barrett (and, with
``--hands allegro pr2``, the other two built-in hands).

For each hand, a small sweep of each object (one process; no reachability: the default ranking
otherwise, p_hold where the hand has a model) into ``--db-dir``, unless the database exists; then the
``--top`` best-ranked grasps of each object (``grasp validate``'s default selection: score > 0) are
trialled in both engines, each at its default settings, the object's stored mass and friction.
Printed per hand: CPU ms per trial of each engine (``time.process_time`` of this process, the first
trial of each object excluded: it builds the world and loads the convex parts), the agreement of the
two verdicts, and the share of objects whose top-1 grasp held in MuJoCo, in PyBullet and in both,
and of the top-10 grasps. None of these objects was used to choose the MuJoCo trial's settings
(those were chosen on ACRONYM tuning objects: bench/acronym_mujoco.py).

    python bench/mujoco_protocols.py [--hands panda barrett allegro pr2] [--objects box cylinder mug ...] [--top 10]
    python bench/mujoco_protocols.py --split held_out_3 --db-dir /tmp/ho3   # 50 random objects never tuned on

``--split NAME`` takes the objects of that list of bench/calibration_split.toml instead of ``--objects``
(``held_out_3``: 50 random objects fixed on 2026-11-23 and never tuned on since; ``held_out_4``: 50 more, drawn
on 2026-12-05 before any of them was swept).

``--grid FILE.json`` (a list of MujocoSettings overrides, dicts; ``{}`` is today's defaults) runs the MuJoCo trial
alone, every configuration on every grasp one after the other (so the machine's load falls on each alike), and
prints per configuration its CPU ms per trial and its verdicts against the first configuration's, grasp by
grasp (how many agree, held -> dropped, dropped -> held, and which), and the share of objects whose top-1 (and of
the top-10 grasps) held; with ``--pybullet`` also PyBullet's trial once a grasp (default settings) and each
configuration's agreement with it (grasps where that configuration has a verdict):

    python bench/mujoco_protocols.py --split tuning --hands panda --grid grid.json --top 20 [--pybullet]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

#: A MuJoCo trial's reason when it has no verdict (planner.validation.mujoco_settings.DIVERGED).
DIVERGED = "diverged"
OBJECTS = ("box", "cylinder", "mug", "duck", "sphere", "teddy", "bunny", "random_100", "random_101", "random_102",
           "random_103", "random_104", "random_105", "random_106", "random_107")
#: A small sweep per hand (the default sweep costs minutes per object on the shared machine).
#: The Allegro (surface rays, six preshapes, 16 joints closed one by one) as the Barrett: 4-30 CPU s an object;
#: the PR2 (surface rays, two preshapes) at its sampler's default 48 rays x 4 rolls: 5-20 CPU s an object.
SWEEPS = {"panda": dict(approaches=256, reach_placements=0),
          "barrett": dict(approaches=24, rolls=2, reach_placements=0),
          "allegro": dict(approaches=24, rolls=2, reach_placements=0),
          "pr2": dict(approaches=48, rolls=4, reach_placements=0)}


#: The calibration split whose lists ``--split`` names.
SPLIT = Path(__file__).with_name("calibration_split.toml")


def split_objects(name: str, path: Path = SPLIT) -> list[str]:
    """The objects of list ``name`` of the calibration split (a one-line exit naming the lists otherwise)."""
    import tomllib

    lists = {k: v for k, v in tomllib.loads(path.read_text()).items() if isinstance(v, list)}
    if name not in lists:
        sys.exit(f"mujoco_protocols: no list {name!r} in {path.name}; it has {', '.join(sorted(lists))}")
    return list(lists[name])


def database(hand: str, objects: tuple[str, ...], folder: Path) -> Path:
    from planner import api
    from planner.plan.sweep import SweepSettings

    db = folder / f"protocols_{hand}.db"
    folder.mkdir(parents=True, exist_ok=True)
    if not db.exists():
        start = time.process_time()
        s = api.generate(list(objects), hand, db_path=db, workers=1, settings=SweepSettings(**SWEEPS[hand]))
        print(f"{hand}: generated {s.grasps} grasps ({s.force_closure} force closure) of {len(objects)} objects in "
              f"{time.process_time() - start:.0f} CPU s", file=sys.stderr, flush=True)
    return db



def top_grasps(db: Path, hand_name: str, objects: list[str], top: int) -> list[tuple[str, object, list]]:
    """(name, the stored object, its ``top`` best grasps) of each of ``objects`` that has grasps in ``db``."""
    from planner.db.objects import stored_object
    from planner.db.store import open_db
    from planner.validation.run import Selection

    with open_db(db, create=False, readonly=True) as handle:
        picked = {o: Selection(top=top).pick(handle, o, hand_name, 0) for o in objects}
        stored = {o: handle.object_row(o) for o in objects}
    out = []
    for name, grasps in picked.items():
        if not grasps or stored[name] is None:
            print(f"{hand_name}/{name}: no grasp", file=sys.stderr)
            continue
        out.append((name, stored_object(stored[name]), grasps))
    return out

def trialled(db: Path, hand_name: str, objects: tuple[str, ...], top: int) -> list[dict]:
    """One row per trialled grasp: object, rank, both verdicts and CPU seconds."""
    from planner.specs.hands import load_hand
    from planner.validation import mujoco_trial, shake

    hand = load_hand(hand_name)
    rows = []
    for name, obj, grasps in top_grasps(db, hand_name, objects, top):
        for engine in (mujoco_trial, shake):  # build the world, load the parts
            engine.trials(hand, obj, grasps[:1])
        for g in grasps:
            out = {"object": name, "rank": g.rank, "force_closure": bool(g.force_closure)}
            for key, engine in (("mujoco", mujoco_trial), ("pybullet", shake)):
                start = time.process_time()
                t = engine.trials(hand, obj, [g])[0]
                out[key] = {"held": bool(t.success), "reason": t.reason, "cpu": time.process_time() - start}
            rows.append(out)
        print(f"{hand_name}/{name}: {len(grasps)} grasps; top-1 MuJoCo {rows[-len(grasps)]['mujoco']['reason']}, "
              f"PyBullet {rows[-len(grasps)]['pybullet']['reason']}", file=sys.stderr, flush=True)
    return rows


def compared(db: Path, hand_name: str, objects: tuple[str, ...], top: int, grid: list[dict],
             pybullet: bool = False) -> list[dict]:
    """``--grid``: one row per grasp, the MuJoCo trial's (held, reason, CPU s) under each configuration
    (``runs``) and, with ``pybullet``, PyBullet's at its default settings (``pybullet``)."""
    from planner.specs.hands import load_hand
    from planner.validation import mujoco_trial, shake
    from planner.validation.mujoco_settings import MujocoSettings

    hand = load_hand(hand_name)
    configs = [MujocoSettings(**extra) for extra in grid]
    rows = []
    for name, obj, grasps in top_grasps(db, hand_name, objects, top):
        for s in configs:  # build the world, load the parts
            mujoco_trial.trials(hand, obj, grasps[:1], s)
        for g in grasps:
            runs = []
            for s in configs:
                start = time.process_time()
                t = mujoco_trial.trials(hand, obj, [g], s)[0]
                runs.append([bool(t.success), t.reason, time.process_time() - start])
            row = {"object": name, "rank": g.rank, "candidate": g.candidate, "runs": runs}
            if pybullet:
                start = time.process_time()
                t = shake.trials(hand, obj, [g])[0]
                row["pybullet"] = [bool(t.success), t.reason, time.process_time() - start]
            rows.append(row)
        print(f"{hand_name}/{name}: {len(grasps)} grasps", file=sys.stderr, flush=True)
    return rows


def show_compared(hand: str, grid: list[dict], rows: list[dict]) -> None:
    for k, extra in enumerate(grid):
        base = [r["runs"][0] for r in rows]
        now = [r["runs"][k] for r in rows]
        both = [(a, b, r) for a, b, r in zip(base, now, rows) if DIVERGED not in (a[1], b[1])]
        lost = [f"{r['object']}#{r['rank']} {a[1]}->{b[1]}" for a, b, r in both if a[0] and not b[0]]
        gained = [f"{r['object']}#{r['rank']} {a[1]}->{b[1]}" for a, b, r in both if b[0] and not a[0]]
        print(f"{hand} {json.dumps(extra)}: CPU {1000 * np.mean([b[2] for b in now]):.2f} ms/trial; verdicts as the "
              f"first's {len(both) - len(lost) - len(gained)} of {len(both)} "
              f"({(len(both) - len(lost) - len(gained)) / max(1, len(both)):.4f}); held {sum(b[0] for b in now)}; "
              f"held -> dropped {lost}; dropped -> held {gained}; diverged {len(rows) - len(both)}", flush=True)
        print(f"    {held_shares(rows, k)}", flush=True)


def held_shares(rows: list[dict], k: int) -> dict:
    """Configuration ``k``'s share of objects whose top-1 grasp held (its best-ranked grasp with a verdict), of the
    top-10 grasps held, and, where the rows have PyBullet's verdicts, its agreement with them (and PyBullet's
    top-1 on the same grasps)."""
    rows = [r for r in rows if r["runs"][k][1] != DIVERGED]
    if not rows:
        return {}
    best = {}
    for r in rows:
        if r["object"] not in best or r["rank"] < best[r["object"]]["rank"]:
            best[r["object"]] = r
    top10 = [r for r in rows if sum(q["object"] == r["object"] and q["rank"] < r["rank"] for q in rows) < 10]
    out = {"grasps": len(rows), "objects": len(best),
           "top1_held": float(np.mean([r["runs"][k][0] for r in best.values()])),
           "top10_held": float(np.mean([r["runs"][k][0] for r in top10]))}
    if all("pybullet" in r for r in rows):
        out["agree_pybullet"] = int(sum(bool(r["runs"][k][0]) == bool(r["pybullet"][0]) for r in rows))
        out["agree_pybullet_share"] = out["agree_pybullet"] / len(rows)
        out["top1_held_pybullet"] = float(np.mean([r["pybullet"][0] for r in best.values()]))
        out["top1_held_both"] = float(np.mean([r["runs"][k][0] and r["pybullet"][0] for r in best.values()]))
    return out


def summary(rows: list[dict]) -> dict:
    """The figures of one hand's rows; a MuJoCo trial that diverged (no verdict) is counted apart and left
    out of every other figure (an object's top-1 is then its best grasp with a verdict)."""
    diverged = sum(r["mujoco"]["reason"] == "diverged" for r in rows)
    rows = [r for r in rows if r["mujoco"]["reason"] != "diverged"]
    if not rows:
        return {}
    mj = np.array([r["mujoco"]["held"] for r in rows])
    pb = np.array([r["pybullet"]["held"] for r in rows])
    first = [r for r in rows if r["rank"] == min(q["rank"] for q in rows if q["object"] == r["object"])]
    top10 = [r for r in rows if sum(q["object"] == r["object"] and q["rank"] < r["rank"] for q in rows) < 10]
    return {
        "grasps": len(rows), "objects": len(first), "diverged_mujoco": diverged,
        "cpu_ms_mujoco": 1000 * float(np.mean([r["mujoco"]["cpu"] for r in rows])),
        "cpu_ms_mujoco_median": 1000 * float(np.median([r["mujoco"]["cpu"] for r in rows])),
        "cpu_ms_pybullet": 1000 * float(np.mean([r["pybullet"]["cpu"] for r in rows])),
        "cpu_ms_pybullet_median": 1000 * float(np.median([r["pybullet"]["cpu"] for r in rows])),
        "agreement": float(np.mean(mj == pb)), "held_mujoco": float(mj.mean()), "held_pybullet": float(pb.mean()),
        "both_held_pb_dropped_mj": int(np.sum(pb & ~mj)), "mj_held_pb_dropped": int(np.sum(mj & ~pb)),
        "top1_mujoco": float(np.mean([r["mujoco"]["held"] for r in first])),
        "top1_pybullet": float(np.mean([r["pybullet"]["held"] for r in first])),
        "top1_both": float(np.mean([r["mujoco"]["held"] and r["pybullet"]["held"] for r in first])),
        "top10_mujoco": float(np.mean([r["mujoco"]["held"] for r in top10])),
        "top10_pybullet": float(np.mean([r["pybullet"]["held"] for r in top10])),
        "top10_not_force_closure": int(sum(not r.get("force_closure", True) for r in top10)),
        "top1_not_held_mujoco": [f"{r['object']} ({r['mujoco']['reason']})" for r in first if not r["mujoco"]["held"]],
        "top1_not_held_pybullet": [f"{r['object']} ({r['pybullet']['reason']})" for r in first
                                   if not r["pybullet"]["held"]],
        "reasons_mujoco": {k: int(sum(r["mujoco"]["reason"] == k for r in rows))
                           for k in sorted({r["mujoco"]["reason"] for r in rows})},
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--hands", nargs="*", default=["panda", "barrett"], choices=sorted(SWEEPS))
    parser.add_argument("--objects", nargs="*", default=list(OBJECTS))
    parser.add_argument("--split", help="the objects of this list of bench/calibration_split.toml (e.g. held_out_3)")
    parser.add_argument("--top", type=int, default=10)
    parser.add_argument("--db-dir", type=Path, default=Path("out"))
    parser.add_argument("--json", type=Path, help="also write every row and the summaries here")
    parser.add_argument("--grid", type=Path, help="JSON list of MujocoSettings overrides: the MuJoCo trial alone")
    parser.add_argument("--pybullet", action="store_true", help="with --grid: also PyBullet's trial, agreement with it")
    args = parser.parse_args()
    if args.split:
        args.objects = split_objects(args.split)
    print(f"load: {os.getloadavg()[0]:.1f}", file=sys.stderr)
    report = {}
    for hand in args.hands:
        db = database(hand, tuple(args.objects), args.db_dir)
        if args.grid:
            grid = json.loads(args.grid.read_text())
            report[hand] = {"grid": grid, "rows": compared(db, hand, tuple(args.objects), args.top, grid,
                                                                  args.pybullet)}
            show_compared(hand, grid, report[hand]["rows"])
            continue
        rows = trialled(db, hand, tuple(args.objects), args.top)
        report[hand] = {"summary": summary(rows), "rows": rows}
        s = report[hand]["summary"]
        print(f"{hand}: {s['grasps']} grasps of {s['objects']} objects; CPU per trial MuJoCo {s['cpu_ms_mujoco']:.1f} "
              f"ms (median {s['cpu_ms_mujoco_median']:.1f}), PyBullet {s['cpu_ms_pybullet']:.1f} ms (median "
              f"{s['cpu_ms_pybullet_median']:.1f}); verdicts agree {s['agreement']:.3f} (held: MuJoCo "
              f"{s['held_mujoco']:.2f}, PyBullet {s['held_pybullet']:.2f}); top-1 held: MuJoCo {s['top1_mujoco']:.2f}, "
              f"PyBullet {s['top1_pybullet']:.2f}, both {s['top1_both']:.2f}; top-10 held: MuJoCo "
              f"{s['top10_mujoco']:.2f}, PyBullet {s['top10_pybullet']:.2f} ({s['top10_not_force_closure']} of them "
              f"not force closure as planned); top-1 dropped in MuJoCo: "
              f"{s['top1_not_held_mujoco']}; MuJoCo reasons {s['reasons_mujoco']}, diverged (left out) "
              f"{s['diverged_mujoco']}", flush=True)
    print(f"load: {os.getloadavg()[0]:.1f}", file=sys.stderr)
    if args.json:
        args.json.write_text(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
