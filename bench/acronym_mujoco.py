"""The MuJoCo trial (and, side by side, the PyBullet trial) against ACRONYM's FleX labels (issue 26 item 6).

For each grasp file of ``../shared/labelled/acronym_dev`` whose object is on the ``tuning`` side of
bench/acronym_split.toml (held-out objects are refused: the lead runs them with
``bench/acronym_eval.py --held-out --engine mujoco``), the poses bench/acronym_eval.py re-scored
(its cache: ``--poses`` per file, seed ``--seed``), of which ``--per-file`` closed poses drawn with
``--sample-seed`` are trialled in MuJoCo (``planner.validation.mujoco_trial.trials``, the file's mass
and friction; ``--set key=value`` overrides MujocoSettings) and, with ``--pybullet``, in PyBullet
(``planner.validation.shake.trials``, at the planner's re-centred pose, as ``grasp validate`` runs it), and the
verdict of both (held only if held in both: what the ranking and the exports' ``trial`` label use).
Printed: agreement with ``object_in_gripper`` pooled, per
category and per object, verdicts by reason against the label, and CPU ms per trial.

``--grid FILE.json``: a list of settings overrides (dicts), each run on the same poses (tuning).
``--render DIR``: pictures of up to ``--per-outcome`` disagreements of each kind (MuJoCo holds what FleX drops,
``holds_flex_drops.png``; MuJoCo drops what FleX holds, ``drops_flex_holds.png``) of the first configuration:
the hand closed at the file's pose as the planner closes it, titled with FleX's own record of the object's
motion while closing and shaking (what to look at before calling either engine wrong).
``--render-moved DIR``: the same pictures of up to ``--per-outcome`` poses of each kind whose verdict the grid's
second configuration moved from the first's (toward FleX, ``moved_toward_flex*.png``; away,
``moved_away_from_flex*.png``; four to a sheet).

    python bench/acronym_mujoco.py [--per-file 10] [--sample-seed 1] [--set shake_angle=0.3] [--pybullet]

Re-scoring results are read from acronym_eval's cache under the code hash ``--code`` (default: this
tree's; re-scoring does not run MuJoCo, so a branch that adds only the MuJoCo trial may reuse the
cache of the code it started from); a file not in the cache is re-scored (minutes per file).
Verdicts are cached too, keyed by the settings and the trial modules' source.
"""

from __future__ import annotations

import argparse
import functools
import hashlib
import json
import sys
import time
from collections import Counter, defaultdict
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import acronym_eval as ae  # noqa: E402
from _settings import parse  # noqa: E402

from planner.datasets import importer  # noqa: E402
from planner.geometry.solid import prepare  # noqa: E402
from planner.validation import mujoco_trial, shake  # noqa: E402
from planner.validation.mujoco_settings import MujocoSettings  # noqa: E402
from planner.validation.settings import ShakeSettings  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
# acronym_eval's cached re-scoring results were pickled by the script run as __main__
sys.modules["__main__"].FileResult = ae.FileResult


def trial_code() -> str:
    """Hash of the trial modules' source (a cached verdict is reused only by the same code)."""
    h = hashlib.sha256()
    sim = ROOT / "planner" / "sim"
    for p in sorted((ROOT / "planner" / "validation").glob("*.py")) + [sim / "mujoco_world.py", sim / "mujoco_mjcf.py",
                                                                       sim / "dynamics.py",
                                                                       ROOT / "planner" / "geometry" / "decompose.py"]:
        if p.name not in ("run.py", "robust.py"):  # what runs and stores trials, not the trials
            h.update(p.read_bytes())
    return h.hexdigest()[:10]


def parts_ready(path: Path) -> bool:
    """Whether the object of a grasp file collides without running CoACD (a primitive, or its convex parts, simplified
    or not, cached on disk): ``--ready`` keeps only those files (CoACD costs minutes a mesh on a busy machine)."""
    from planner import assets
    from planner.geometry.decompose import ready_parts
    from planner.validation.parts import MAX_VERTICES, PRIMITIVES, SIMPLIFY_VERSION

    _hand, obj, _poses = _prepared(path)
    tolerance = MujocoSettings().part_tolerance
    name = assets.sha256_bytes(json.dumps([obj.mesh_hash, float(tolerance), MAX_VERTICES, SIMPLIFY_VERSION]).encode())
    return obj.spec.kind in PRIMITIVES or (assets.cache_dir("simplified") / f"{name[:24]}.npz").is_file() or \
        ready_parts(obj.mesh, obj.mesh_hash) is not None


def picked(result: ae.FileResult, n: int, seed: int) -> list[int]:
    closed = np.flatnonzero(result.closed)
    return [int(closed[i]) for i in ae.sample(len(closed), n, seed, result.path.stem)] if len(closed) else []


#: What ``run(..., full=True)`` adds after [held, reason, cpu seconds]: the Trial's continuous record.
FULL = ("closing_linear", "closing_angular", "shaking_linear", "shaking_angular", "fingers_in_contact")


def run(result: ae.FileResult, positions: list[int], engine: str, settings, cache: Path,  # type: ignore[no-untyped-def]
        pose: str = "original", full: bool = False, cached_only: bool = False) -> dict:
    """{position: [held, reason, cpu seconds]} for the sampled poses of one file (cached); ``pose``:
    the file's own pose (``original``, what FleX simulated) or the planner's re-centred one (``planned``).
    ``full``: each list goes on with the Trial's fields named in FULL (metres, radians, fingers; cached apart).
    ``cached_only``: {} where nothing is cached (nothing run)."""
    tag = hashlib.sha256((engine + pose + settings.to_json() + trial_code() + ("full" if full else ""))
                         .encode()).hexdigest()[:12]
    key = cache / f"{result.path.stem}.{engine}.{len(result.rows)}.{'-'.join(map(str, positions))[:60]}." \
                  f"{hashlib.sha256(str(positions).encode()).hexdigest()[:8]}.{tag}.json"
    if key.exists():
        return {int(k): v for k, v in json.loads(key.read_text()).items()}
    if cached_only:
        return {}
    hand, obj, poses = _prepared(result.path)
    by_pos = {g.candidate: g if pose == "planned" else replace(g, pose=poses[result.rows[g.candidate]])
              for g in result.grasps}
    run_trials = mujoco_trial.trials if engine == "mujoco" else shake.trials
    run_trials(hand, obj, [by_pos[positions[0]]], settings)  # builds and caches the world / parts first
    out = {}
    for p in positions:
        start = time.process_time()
        t = run_trials(hand, obj, [by_pos[p]], settings)[0]
        out[p] = [bool(t.success), t.reason, time.process_time() - start] + \
            ([float(getattr(t, f)) for f in FULL] if full else [])
    key.write_text(json.dumps(out))
    return out


@functools.lru_cache(maxsize=2)
def _prepared(path: Path):  # type: ignore[no-untyped-def]
    """(hand, prepared object with the file's mass and friction, (n, 4, 4) hand poses) of a grasp file."""
    hand, spec, poses = importer.read_for_rescoring(path)
    return hand, prepare(spec), poses


def summarise(results: list[ae.FileResult], verdicts: dict[str, dict]) -> dict:
    rows = []
    for r in results:
        v = verdicts.get(r.path.stem, {})
        for p, (held, reason, cpu) in v.items():
            category, obj = ae.object_key(r.path)
            rows.append({"category": category, "object": obj, "flex": int(r.labels[p]), "held": int(held),
                         "reason": reason, "cpu": cpu})
    if not rows:
        return {}
    agree = np.array([r["flex"] == r["held"] for r in rows])
    per_object: dict = defaultdict(list)
    per_category: dict = defaultdict(list)
    for r, a in zip(rows, agree):
        per_object[r["object"]].append(a)
        per_category[r["category"]].append(a)
    objects = {o: float(np.mean(a)) for o, a in per_object.items()}
    by_cat_objects: dict = defaultdict(list)
    for o, a in objects.items():
        by_cat_objects[o.split("_")[0]].append(a)
    return {
        "n": len(rows), "agree": float(agree.mean()),
        "agree_mean_over_objects": float(np.mean(list(objects.values()))),
        "held_rate": float(np.mean([r["held"] for r in rows])), "flex_rate": float(np.mean([r["flex"] for r in rows])),
        "drops_flex_holds": int(sum(r["flex"] == 1 and not r["held"] for r in rows)),
        "holds_flex_drops": int(sum(r["flex"] == 0 and r["held"] for r in rows)),
        "categories": {c: {"n": len(a), "agree": float(np.mean(a)),
                           "mean_over_objects": float(np.mean(by_cat_objects[c]))}
                       for c, a in sorted(per_category.items())},
        "reasons": dict(Counter(f"{r['reason']}/{'hold' if r['flex'] else 'drop'}" for r in rows)),
        "cpu_ms_mean": 1000 * float(np.mean([r["cpu"] for r in rows])),
        "cpu_ms_median": 1000 * float(np.median([r["cpu"] for r in rows])),
    }


def changes(results: list[ae.FileResult], first: dict[str, dict], other: dict[str, dict]) -> dict:
    """How ``other``'s verdicts differ from ``first``'s, pose by pose: the poses both have a verdict of (neither
    diverged), those with the same verdict, and each change named (file stem, sampled position, FleX's label,
    the reasons)."""
    same, changed = 0, []
    for r in results:
        a, b = first.get(r.path.stem, {}), other.get(r.path.stem, {})
        for p in sorted(set(a) & set(b)):
            if "diverged" in (a[p][1], b[p][1]):
                continue
            if bool(a[p][0]) == bool(b[p][0]):
                same += 1
            else:
                changed.append(f"{r.path.stem[:20]}@{p} FleX {'holds' if r.labels[p] else 'drops'}: "
                               f"{a[p][1]} -> {b[p][1]}")
    return {"poses": same + len(changed), "same": same, "changed": changed}


def show(name: str, s: dict) -> None:
    if not s:
        print(f"{name}: no trials")
        return
    cats = ", ".join(f"{c} {v['agree']:.2f} ({v['n']})" for c, v in s["categories"].items())
    print(f"{name}: agree {s['agree']:.3f} of {s['n']} (mean over objects {s['agree_mean_over_objects']:.3f}); "
          f"held {s['held_rate']:.2f} vs FleX {s['flex_rate']:.2f}; drops FleX-holds {s['drops_flex_holds']}, "
          f"holds FleX-drops {s['holds_flex_drops']}; CPU {s['cpu_ms_mean']:.1f} ms/trial (median "
          f"{s['cpu_ms_median']:.1f})\n    by category: {cats}\n    reasons: {s['reasons']}")


def render(results: list[ae.FileResult], verdicts: dict[str, dict], out: Path, per_kind: int, seed: int) -> None:
    """Up to ``per_kind`` pictures of each kind of disagreement with FleX (drawn at random, ``seed``)."""
    kinds: dict[str, list] = {"holds_flex_drops": [], "drops_flex_holds": []}
    for r in results:
        for p, (held, reason, _cpu) in verdicts.get(r.path.stem, {}).items():
            flex = int(r.labels[p])
            if reason != "diverged" and bool(held) != bool(flex):
                kinds["holds_flex_drops" if held else "drops_flex_holds"].append((r, p, f"MuJoCo {reason}"))
    rng = np.random.default_rng(seed)
    for kind, cases in kinds.items():
        sheet([cases[i] for i in sorted(rng.permutation(len(cases))[:per_kind])], out / f"{kind}.png", len(cases))


def render_moved(results: list[ae.FileResult], first: dict[str, dict], other: dict[str, dict], out: Path,
                 per_kind: int, seed: int) -> None:
    """Pictures of up to ``per_kind`` poses (drawn at random, ``seed``) of those whose verdict ``other`` moved from
    ``first``'s toward FleX's (``moved_toward_flex*.png``: now as FleX) and away (``moved_away_from_flex*.png``), four
    to a sheet."""
    kinds: dict[str, list] = {"moved_toward_flex": [], "moved_away_from_flex": []}
    for r in results:
        a, b = first.get(r.path.stem, {}), other.get(r.path.stem, {})
        for p in sorted(set(a) & set(b)):
            if "diverged" not in (a[p][1], b[p][1]) and bool(a[p][0]) != bool(b[p][0]):
                toward = bool(b[p][0]) == bool(r.labels[p])
                kinds["moved_toward_flex" if toward else "moved_away_from_flex"].append(
                    (r, p, f"MuJoCo {a[p][1]} -> {b[p][1]}"))
    rng = np.random.default_rng(seed)
    for kind, cases in kinds.items():
        drawn = [cases[i] for i in sorted(rng.permutation(len(cases))[:per_kind])]
        for k in range(0, len(drawn), 4):
            sheet(drawn[k:k + 4], out / f"{kind}{k // 4}.png", len(cases))


def sheet(cases: list[tuple[ae.FileResult, int, str]], path: Path, of: int) -> None:
    """One row per (file, sampled position, verdict text): the hand closed at the file's pose as the planner
    closes it, titled with FleX's record of the object's motion."""
    import h5py

    from planner.present.render import grasp_views, save_sheet

    panels = []
    for r, p, verdict in cases:
        hand, obj, poses = _prepared(r.path)
        grasp = next(g for g in r.grasps if g.candidate == p)
        grasp = replace(grasp, pose=poses[r.rows[p]])
        with h5py.File(r.path, "r") as f:
            q = f["grasps/qualities/flex"]
            motion = [float(q[f"object_motion_during_{phase}_{kind_}"][r.rows[p]])
                      for phase in ("closing", "shaking") for kind_ in ("linear", "angular")]
        panels.append((grasp_views(hand, obj, grasp),
                       f"{r.path.stem[:40]} row {r.rows[p]}: FleX {'holds' if r.labels[p] else 'drops'} "
                       f"(object moved {100 * motion[0]:.1f} cm / {motion[1]:.2f} rad closing, "
                       f"{100 * motion[2]:.1f} cm / {motion[3]:.2f} rad shaking); {verdict}; "
                       f"width {1000 * (grasp.width or 0.0):.1f} mm"))
    if panels:
        save_sheet(panels, path)
        print(f"wrote {path} ({len(panels)} of {of})", file=sys.stderr)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--dev", type=Path, default=ae.DEV)
    parser.add_argument("--poses", type=int, default=200, help="acronym_eval's re-scored sample per file")
    parser.add_argument("--seed", type=int, default=0, help="acronym_eval's re-scoring seed")
    parser.add_argument("--per-file", type=int, default=10, help="closed poses trialled per file")
    parser.add_argument("--sample-seed", type=int, default=1)
    parser.add_argument("--objects", nargs="*", help="only these Category_id objects (tuning side)")
    parser.add_argument("--files", type=int, default=0, help="only the first N files (0: all)")
    parser.add_argument("--ready", action="store_true", help="only files whose object's convex parts are cached")
    parser.add_argument("--set", dest="overrides", nargs="*", default=[], help="MujocoSettings key=value")
    parser.add_argument("--grid", type=Path, help="JSON list of MujocoSettings overrides, each run")
    parser.add_argument("--pose", choices=("original", "planned"), default="original",
                        help="start each MuJoCo trial at the file's pose (what FleX simulated) or the planner's")
    parser.add_argument("--pybullet", action="store_true", help="also the PyBullet trial (default settings)")
    parser.add_argument("--code", help="re-scoring cache code (default: this tree's acronym_eval.source_hash)")
    parser.add_argument("--cache", type=Path, default=ae.CACHE)
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--render", type=Path, help="draw disagreements with FleX into this folder")
    parser.add_argument("--per-outcome", type=int, default=4, help="pictures per kind of disagreement")
    parser.add_argument("--render-moved", type=Path, help="draw poses whose verdict the grid's second "
                                                          "configuration moved into this folder")
    args = parser.parse_args()
    files = ae.dev_files(args.dev, False, args.objects)
    if args.files:
        files = files[:args.files]
    if args.ready:
        files = [p for p in files if parts_ready(p)]
        print(f"{len(files)} files whose objects' parts are cached", file=sys.stderr)
    code = args.code or ae.source_hash()
    results = [ae.rescore_file(p, args.poses, args.seed, 1, args.cache, code) for p in files]
    base = parse(args.overrides, MujocoSettings, "acronym_mujoco")
    grid = json.loads(args.grid.read_text()) if args.grid else [{}]
    report: dict = {"files": len(files), "per_file": args.per_file, "sample_seed": args.sample_seed, "code": code,
                    "trial_code": trial_code(), "pose": args.pose, "runs": []}
    configs = [MujocoSettings(**{**base, **extra}) for extra in grid]
    verdicts: list[dict] = [{} for _ in configs]
    start = time.process_time()
    for r in results:  # files outer: each object is loaded once for every configuration
        for k, settings in enumerate(configs):
            verdicts[k][r.path.stem] = run(r, picked(r, args.per_file, args.sample_seed), "mujoco", settings,
                                           args.cache, args.pose)
    report_verdicts = verdicts[0]  # the first configuration's, for --pybullet's "both"
    for extra, v in zip(grid, verdicts):
        s = summarise(results, v)
        s["settings"] = {**base, **extra}
        s["against_first"] = changes(results, verdicts[0], v)
        report["runs"].append(s)
        if not args.json:
            show(f"mujoco {json.dumps({**base, **extra})}", s)
            print(f"    against the first configuration, pose by pose: {s['against_first']}")
    report["cpu_seconds"] = time.process_time() - start
    if args.render:
        render(results, verdicts[0], args.render, args.per_outcome, args.sample_seed)
    if args.render_moved and len(verdicts) > 1:
        render_moved(results, verdicts[0], verdicts[1], args.render_moved, args.per_outcome, args.sample_seed)
    if args.pybullet:
        settings_pb = ShakeSettings()
        verdicts = {r.path.stem: run(r, picked(r, args.per_file, args.sample_seed), "pybullet", settings_pb,
                                     args.cache, "planned") for r in results}  # its trial starts near the plan
        report["pybullet"] = summarise(results, verdicts)
        if not args.json:
            show("pybullet (default ShakeSettings)", report["pybullet"])
        # what the ranking and the exports' trial label use: held only if held in every protocol that tried it
        both = {stem: {p: [bool(v[p][0]) and bool(mj[p][0]), "both", v[p][2] + mj[p][2]] for p in v}
                for stem, v in verdicts.items() for mj in [report_verdicts[stem]]}
        report["both"] = summarise(results, both)
        if not args.json:
            show("held in both (the ranking's and the labels' trial verdict)", report["both"])
    if args.json:
        print(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
