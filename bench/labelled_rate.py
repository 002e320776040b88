"""The headline figure (issue 24, item 3): force-closure grasps and trial-labelled grasps per core-second, per
hand, on the built-ins, on random objects and on a scan-like mesh, with the previous run side by side.

    python bench/labelled_rate.py [--tree REV] [--hand panda --hand barrett] [--builtins mug duck box]
                                  [--random 3] [--scan-faces 100000] [--trials 40] [--save] [--previous FILE]
                                  [--repeat N] [--against REV]

Per hand and object, one child process (one core) of the tree (this checkout, or ``--tree REV`` unpacked with
``git archive``) runs one unit of the hand's default sweep (the hand's sampler, preshapes, rolls and settle; the
Panda: one default unit of 256 antipodal points, 4,096 candidates; ray hands: ``--rays`` rays; no
reachability), then trials a seeded sample of up to ``--trials`` of its force-closure grasps with
``--engine``'s trial at its default settings (default: ``grasp validate``'s engine, the tree's ``DEFAULT_ENGINE``;
``pybullet``: ``planner.validation.shake.trials``, ``mujoco``: ``planner.validation.mujoco_trial.trials``).
Objects: ``--builtins``, ``random_000`` ..
(``--random`` of them), and a scan-like capsule (``tests/scanlike.py``: 4.4 x 11.4 cm, ``--scan-faces`` faces,
an OBJ with UV-split vertices). The object's check, its collision proxy and its convex parts are made before
the clock starts (a one-time cost per object, cached on disk), and so is the MuJoCo trial's world (built once per
object and process, as ``grasp validate``'s workers do; until 2026-12-03 inside the trials' clock: a few to
~100 ms over 40 trials).

Figures, CPU seconds of the child (``time.process_time``), summed over a group's objects:

- FC/s: force-closure grasps per CPU second of the sweep;
- labelled/s: force-closure grasps per CPU second when each is also shake-tested, sweep plus trials, the trials
  costed at the sample's mean CPU time per trial: FC / (sweep CPU + FC x trial CPU);
- trial ms: CPU per shake trial; held: share of the sample that held.

The run is written to ``--previous`` (default ``bench/labelled_rate.json``) with ``--save``; the next run prints
those figures beside its own.

A host's CPU time for the same work can move by 5-10% from one run to the next (neighbours on shared hardware). Two
options make a comparison hold against that: ``--repeat N`` runs each object's child N times and keeps the least
sweep and the least trial CPU (the work is the same every time: the runs must agree on the counts); ``--against REV``
runs a second tree beside the first, each object's children alternating between the two trees, and prints that
tree's figures in the brackets instead of ``--previous``'s (``--save`` still writes the first tree's).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _trees import ROOT, unpack, uptime

PREVIOUS = ROOT / "bench" / "labelled_rate.json"
GROUPS = ("built-ins", "random", "scan")


# -- child ----------------------------------------------------------------------------------------------------------
def child(obj: str, hand: str, rays: int, trials: int, out: str, engine: str | None) -> None:
    import planner
    from planner.geometry.solid import load_object
    from planner.plan.sweep import SweepSettings
    from planner.plan.unit import UnitSpec, run_unit
    from planner.specs.hands import load_hand
    from planner.validation.parts import trial_shape
    from planner.validation.shake import ShakeSettings
    from planner.validation.shake import trials as shake

    try:  # a tree before the MuJoCo trial has the PyBullet trial alone
        from planner.validation.mujoco_settings import DEFAULT_ENGINE
    except ImportError:
        DEFAULT_ENGINE = "pybullet"
    engine = engine or DEFAULT_ENGINE
    if engine == "mujoco":
        from planner.validation.mujoco_settings import MujocoSettings
        from planner.validation.mujoco_trial import trials as mujoco

        def run_trials(spec, obj, grasps):  # type: ignore[no-untyped-def]
            return mujoco(spec, obj, grasps, MujocoSettings())
    else:
        def run_trials(spec, obj, grasps):  # type: ignore[no-untyped-def]
            return shake(spec, obj, grasps, ShakeSettings())
    spec = load_hand(hand)
    prepared = load_object(obj)
    w0 = time.process_time()
    try:  # the collision proxy, where the tree has one, outside the clock
        from planner.geometry.proxy import collision_proxy

        collision_proxy(prepared.mesh, prepared.mesh_hash)
    except ImportError:
        pass
    trial_shape(prepared, ShakeSettings().part_tolerance)
    if engine == "mujoco":  # its world (hand and parts compiled), built once per object and process, too
        try:
            from planner.validation.mujoco_worlds import world_for

            world_for(spec, prepared, MujocoSettings(), prepared.mass)
        except ImportError:
            pass
    warm = time.process_time() - w0
    approaches = 256 if spec.sampler == "antipodal" else rays
    t0 = time.process_time()
    r = run_unit(UnitSpec(obj, hand, SweepSettings(approaches=approaches, chunk=0, reach_placements=0), 0))
    sweep = time.process_time() - t0
    fc = sorted((g for g in r.grasps if g.force_closure), key=lambda g: g.candidate)
    rng = np.random.default_rng(0)
    picked = [fc[i] for i in sorted(rng.choice(len(fc), size=min(trials, len(fc)), replace=False))] if fc else []
    t1 = time.process_time()
    verdicts = run_trials(spec, r.obj, picked) if picked else []
    trial = time.process_time() - t1
    Path(out).write_text(json.dumps({
        "planner": str(Path(planner.__file__).resolve().parent.parent), "error": r.error, "warm": warm,
        "candidates": r.candidates, "grasps": len(r.grasps), "fc": len(fc), "sweep": sweep,
        "tested": len(picked), "held": sum(bool(v.success) for v in verdicts), "trial": trial, "engine": engine,
        "timing": r.timing}))


def _least(runs: list[dict]) -> dict:
    """One object's figures from repeated runs of the same work: the least sweep and trial CPU; an error if any run
    failed or the runs disagree on what they found."""
    failed = [r for r in runs if r.get("error")]
    if failed:
        return failed[0]
    counts = {(r["candidates"], r["grasps"], r["fc"], r["tested"], r["held"]) for r in runs}
    if len(counts) > 1:
        return {"error": f"repeated runs found different grasps: {sorted(counts)}"}
    return {**runs[0], "sweep": min(r["sweep"] for r in runs), "trial": min(r["trial"] for r in runs),
            "sweeps": [r["sweep"] for r in runs], "trials": [r["trial"] for r in runs]}


def _run(tree: Path, obj: str, hand: str, args: argparse.Namespace, out: Path) -> dict:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tree), *filter(None, [os.environ.get("PYTHONPATH")])]),
               GRASP_HOME=str(tree))
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", obj, "--hand", hand, "--rays", str(args.rays),
           "--trials", str(args.trials), "--json-out", str(out), *(["--engine", args.engine] if args.engine else [])]
    done = subprocess.run(cmd, env=env, cwd=tree, capture_output=True, text=True)
    if done.returncode or not out.exists():
        return {"error": f"child failed (exit {done.returncode}): {done.stderr.strip().splitlines()[-1:]}"}
    data = json.loads(out.read_text())
    if Path(data["planner"]).resolve() != tree.resolve():
        raise SystemExit(f"the child imported planner from {data['planner']}, not {tree}")
    return data


# -- figures --------------------------------------------------------------------------------------------------------
def group_figures(rows: list[dict]) -> dict:
    """FC/s, labelled/s, trial ms, held share, candidates/s over a group's objects."""
    rows = [r for r in rows if not r.get("error")]
    if not rows:
        return {}
    fc = sum(r["fc"] for r in rows)
    sweep = sum(r["sweep"] for r in rows)
    tested = sum(r["tested"] for r in rows)
    per_trial = sum(r["trial"] for r in rows) / tested if tested else float("nan")
    return {"objects": len(rows), "candidates": sum(r["candidates"] for r in rows), "fc": fc, "sweep_cpu": sweep,
            "candidates/s": sum(r["candidates"] for r in rows) / sweep, "FC/s": fc / sweep,
            "labelled/s": fc / (sweep + fc * per_trial) if tested else float("nan"),
            "trial ms": 1000 * per_trial, "held": sum(r["held"] for r in rows) / tested if tested else float("nan")}


def _print(figures: dict, previous: dict | None, bracketed: str = "previous run") -> None:
    keys = ("objects", "candidates", "fc", "candidates/s", "FC/s", "labelled/s", "trial ms", "held")
    for hand, groups in figures["hands"].items():
        print(f"\n## {hand}")
        print(f"{'group':10s} " + " ".join(f"{k:>13s}" for k in keys) + f"   ({bracketed} in brackets)")
        for group in (*GROUPS, "all"):
            now = groups.get(group, {})
            before = ((previous or {}).get("hands", {}).get(hand, {}).get(group, {}))
            cells = []
            for k in keys:
                a, b = now.get(k), before.get(k)
                text = "-" if a is None else (f"{a:d}" if isinstance(a, int) else f"{a:.3g}")
                if b is not None:
                    text += f" [{b:d}]" if isinstance(b, int) else f" [{b:.3g}]"
                cells.append(f"{text:>13s}")
            print(f"{group:10s} " + " ".join(cells))
        for group, rows in figures["objects"][hand].items():
            for name, r in rows.items():
                if r.get("error"):
                    print(f"  {group}/{name}: error: {r['error']}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--tree", help="git commit to run instead of this checkout")
    parser.add_argument("--hand", action="append")
    parser.add_argument("--builtins", nargs="+", default=["mug", "duck", "box"])
    parser.add_argument("--random", type=int, default=3)
    parser.add_argument("--scan-faces", type=int, default=100_000)
    parser.add_argument("--rays", type=int, default=8, help="rays per unit for the ray-sampling hands")
    parser.add_argument("--trials", type=int, default=40)
    parser.add_argument("--engine", choices=("pybullet", "mujoco"), help="the trial (default: the tree's default)")
    parser.add_argument("--previous", type=Path, default=PREVIOUS)
    parser.add_argument("--save", action="store_true", help="write this run to --previous")
    parser.add_argument("--compare", type=Path, help="show these figures beside this run's (default: --previous)")
    parser.add_argument("--repeat", type=int, default=1, help="runs per object and tree; the least CPU is kept")
    parser.add_argument("--against", help="a second git commit, run alternately with the first, shown in brackets")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    parser.add_argument("--json-out", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args.child, args.hand[0], args.rays, args.trials, args.json_out, args.engine)
        return
    if args.repeat < 1:
        parser.error("--repeat must be at least 1")
    hands = args.hand or ["panda", "barrett"]
    sys.path.insert(0, str(ROOT / "tests"))
    import scanlike

    label = args.tree or "HEAD"
    print(f"# labelled_rate: tree {label}{f' against {args.against}' if args.against else ''}, hands {hands}, "
          f"built-ins {args.builtins}, random {args.random}, scan {args.scan_faces} faces, {args.trials} trials per "
          f"object, {args.repeat} run(s) each; {platform.machine()}, {os.cpu_count()} cores, "
          f"Python {platform.python_version()}")
    print(f"# {time.strftime('%Y-%m-%d %H:%M')} start: {uptime()}")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for side in ("tree", "against"):
            (folder / side).mkdir()
        tree = unpack(args.tree, folder / "tree") if args.tree else ROOT
        other = unpack(args.against, folder / "against") if args.against else None
        scan = folder / f"scan_capsule_{args.scan_faces}.obj"
        scan.write_text(scanlike.uv_obj(args.scan_faces))
        objects = {"built-ins": list(args.builtins), "random": [f"random_{i:03d}" for i in range(args.random)],
                   "scan": [str(scan)]}
        sides = {"tree": (tree, label, args.tree or "HEAD")}
        if other is not None:
            sides["against"] = (other, args.against, args.against)
        runs: dict = {}
        for side, (_, name, rev) in sides.items():
            runs[side] = {"tree": name, "date": time.strftime("%Y-%m-%d %H:%M"), "hands": {}, "objects": {},
                          "commit": subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", rev],
                                                   capture_output=True, text=True).stdout.strip()}
        for hand in hands:
            for side in sides:
                runs[side]["objects"][hand] = {}
            for group, names in objects.items():
                rows: dict = {side: {} for side in sides}
                for name in names:
                    key = Path(name).stem if group == "scan" else name
                    tries: dict = {side: [] for side in sides}
                    for i in range(args.repeat):
                        for side, (root, _, _) in sides.items():  # alternating: a slow spell hits both sides
                            tries[side].append(_run(root, name, hand, args, folder / f"{side}_{hand}_{key}_{i}.json"))
                    for side in sides:
                        rows[side][key] = _least(tries[side])
                        brief = {k: rows[side][key].get(k) for k in ("fc", "sweep", "tested", "trial", "error")}
                        print(f"#   {hand} {key}{' (' + sides[side][1] + ')' if other else ''}: {json.dumps(brief)}",
                              flush=True)
                for side in sides:
                    runs[side]["objects"][hand][group] = rows[side]
            for side in sides:
                found = runs[side]["objects"][hand]
                groups = {g: group_figures(list(found[g].values())) for g in objects}
                groups["all"] = group_figures([r for g in objects for r in found[g].values()])
                runs[side]["hands"][hand] = groups
    figures = runs["tree"]
    print(f"# end: {uptime()}")
    if other is not None:
        previous = runs["against"]
        print(f"# in brackets: {args.against}, run alternately with {label}")
    else:
        shown = args.compare or args.previous
        previous = json.loads(shown.read_text()) if shown.is_file() else None  # read now: it may be newer
        if previous:
            print(f"# previous run: {previous.get('tree')} at {previous.get('date')} ({previous.get('commit')})")
    _print(figures, previous, f"{args.against}, run alternately," if other is not None else "previous run")
    if args.save:
        args.previous.write_text(json.dumps(figures, indent=1) + "\n")
        print(f"# written to {args.previous}")


if __name__ == "__main__":
    main()
