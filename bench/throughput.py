"""Candidates, force-closure and validated grasps per second per core, with a
per-stage breakdown, before (an earlier commit) and after (this tree) side by side.

    python bench/throughput.py [--before REV] [--object mug] [--hand H ...] [--approaches 24] [--seed 0]
                               [--validate 40]

``--before`` (default :data:`BEFORE`; ``none``: this tree only) is unpacked
with ``git archive`` into a temporary folder. Each side runs in its own child
process (one core) with its tree first on ``PYTHONPATH``, ``GRASP_HOME`` set
to that tree and its own ``GRASP_CACHE`` sub-folder (``$GRASP_CACHE`` or the
temporary folder, then ``throughput/before`` and ``throughput/after``: the
object is checked, and its convex parts made, once per side). Per hand
(default: every hand of this tree), each child runs what the figures are
about, one after another:

1. one unit, ``run_unit(UnitSpec(object, hand, SweepSettings(approaches=N), seed))``
   (the hand's default sampler, preshapes, rolls, standoffs, settle and
   reachability), then writes it to a scratch database;
2. shake-tests a seeded uniform sample of the unit's grasps (``--validate N``,
   0 skips it) with the default trial, one world per trial.

Printed per hand, before, after and after/before: candidates, grasps with
contacts, force-closure grasps, grasps shake-tested and held; candidates and
force-closure grasps per CPU second of the unit and its database write
(object loading included, from a cache warmed before the clock starts);
validated (shake-tested) grasps per CPU second of the trials (convex parts
prepared before the clock starts); the unit's CPU and wall seconds; CPU
milliseconds per candidate of each stage (``result.timing`` plus the
database write; a stage a tree does not time prints ``-``); and the
rejection reasons. All rates are CPU time of the child
(``time.process_time``; the stages' own ``perf_counter`` timers are switched
to it, see ``bench/_trees.py``). The machine may be shared: CPU time is the
steadier figure; the load average is printed at start and end.
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
from _trees import ROOT, cpu_clocks, unpack, uptime

#: main before this session's work (the settled-epsilon commit, 2026-11-23): the "before" side by default.
BEFORE = "b7a6629"

#: Stage columns, in pipeline order (``result.timing`` keys, plus the database write).
STAGES = ("prepare", "sampling", "rejection", "closing", "contacts", "quality", "settle", "reachability", "database")


# -- child: runs inside one tree ---------------------------------------------------------------
def validated_rate(result, hand: str, count: int, seed: int) -> dict:  # type: ignore[no-untyped-def]
    """Shake-test a seeded uniform sample of ``count`` of the unit's grasps:
    grasps tested, held, and CPU / wall seconds of the trials."""
    from planner.specs.hands import load_hand
    from planner.validation.parts import trial_shape
    from planner.validation.shake import ShakeSettings, trials

    grasps = sorted(result.grasps, key=lambda g: g.candidate)
    if count <= 0 or not grasps:
        return {"tested": 0, "held": 0, "cpu": 0.0, "wall": 0.0}
    rng = np.random.default_rng(seed)
    picked = [grasps[i] for i in sorted(rng.choice(len(grasps), size=min(count, len(grasps)), replace=False))]
    settings = ShakeSettings()
    trial_shape(result.obj, settings.part_tolerance)  # CoACD parts: prepared (and cached) outside the clock
    hand_spec = load_hand(hand)
    w0, t0 = time.perf_counter(), time.process_time()
    out = trials(hand_spec, result.obj, picked, settings)
    cpu, wall = time.process_time() - t0, time.perf_counter() - w0
    return {"tested": len(picked), "held": sum(bool(getattr(t, "success", False)) for t in out), "cpu": cpu,
            "wall": wall}


def bench(obj: str, hand: str, approaches: int, seed: int, validate: int = 0) -> dict:
    """One hand: the unit, its database write and the shake-test sample (CPU and wall seconds)."""
    from planner.api import unit_row
    from planner.db.store import open_db
    from planner.plan.sweep import SweepSettings
    from planner.plan.unit import UnitSpec, run_unit

    settings = SweepSettings(approaches=approaches)
    w0, t0 = time.perf_counter(), time.process_time()
    result = run_unit(UnitSpec(obj, hand, settings, seed))
    cpu, wall = time.process_time() - t0, time.perf_counter() - w0
    if result.error:
        return {"hand": hand, "error": result.error}
    with tempfile.TemporaryDirectory() as tmp, open_db(Path(tmp) / "bench.db") as db:
        w1, t1 = time.perf_counter(), time.process_time()
        db.write_unit(unit_row(result, wall), result.obj, result.grasps, db.rule())
        db_cpu, db_wall = time.process_time() - t1, time.perf_counter() - w1
    return {"hand": hand, "candidates": result.candidates, "grasps": len(result.grasps), "fc": result.force_closure,
            "cpu": cpu + db_cpu, "wall": wall + db_wall, "timing": dict(result.timing, database=db_cpu),
            "rejected": dict(result.rejected), "validated": validated_rate(result, hand, validate, seed)}


def _warm(obj: str, validate: int) -> None:
    """Check the object's mesh, and make its convex parts, into this side's cache, outside any clock."""
    from planner.geometry.solid import load_object
    from planner.validation.parts import trial_shape
    from planner.validation.shake import ShakeSettings

    prepared = load_object(obj)
    if validate > 0:
        trial_shape(prepared, ShakeSettings().part_tolerance)


def child(args: argparse.Namespace) -> None:
    import planner
    from planner.specs.hands import hand_names

    switched = cpu_clocks()
    w0, t0 = time.perf_counter(), time.process_time()
    _warm(args.object, args.validate)
    warm = {"cpu": time.process_time() - t0, "wall": time.perf_counter() - w0}
    known = set(hand_names())
    hands = {h: bench(args.object, h, args.approaches, args.seed, args.validate) if h in known
             else {"hand": h, "error": "no such hand in this tree"} for h in args.hand}
    out = {"planner": str(Path(planner.__file__).resolve().parent.parent), "clocks": switched, "warm": warm,
           "hands": hands}
    Path(args.json_out).write_text(json.dumps(out))


# -- parent ---------------------------------------------------------------------------------------
def _side(tree: Path, cache: Path, args: argparse.Namespace, out: Path) -> dict:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tree), *filter(None, [os.environ.get("PYTHONPATH")])]),
               GRASP_CACHE=str(cache), GRASP_HOME=str(tree))
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", "--json-out", str(out), "--object", args.object,
           "--approaches", str(args.approaches), "--seed", str(args.seed), "--validate", str(args.validate)]
    for hand in args.hand:
        cmd += ["--hand", hand]
    w0 = time.perf_counter()
    done = subprocess.run(cmd, env=env, cwd=tree, capture_output=True, text=True)
    if done.returncode or not out.exists():
        tail = "\n".join(done.stderr.strip().splitlines()[-20:])
        raise SystemExit(f"{tree}: child failed (exit {done.returncode}):\n{tail}")
    data = json.loads(out.read_text())
    if Path(data["planner"]).resolve() != tree.resolve():
        raise SystemExit(f"the child imported planner from {data['planner']}, not {tree}")
    data["wall"] = time.perf_counter() - w0
    return data


def _figures(r: dict) -> dict[str, float | int | str]:
    """The rows of one side's table for one hand ('-' where the side has no figure)."""
    if "error" in r:
        return {}
    n, v, t = max(r["candidates"], 1), r["validated"], r["timing"]
    rows: dict[str, float | int | str] = {
        "candidates": r["candidates"], "grasps with contacts": r["grasps"], "force-closure grasps": r["fc"],
        "shake-tested": v["tested"], "held": v["held"],
        "candidates/s/core": r["candidates"] / r["cpu"], "FC grasps/s/core": r["fc"] / r["cpu"],
        "validated grasps/s/core": v["tested"] / v["cpu"] if v["tested"] and v["cpu"] > 0 else "-",
        "unit + database CPU s": r["cpu"], "unit + database wall s": r["wall"],
        "validation CPU s": v["cpu"], "validation wall s": v["wall"],
    }
    for k in (*STAGES, *sorted(set(t) - set(STAGES))):
        rows[f"{k} ms/candidate"] = 1000 * t[k] / n if k in t else "-"
    return rows


def _cell(x: float | int | str | None) -> str:
    if x is None or isinstance(x, str):
        return f"{x or '-':>10s}"
    return f"{x:10d}" if isinstance(x, int) else f"{x:10.2f}"


def _ratio(before: float | int | str | None, after: float | int | str | None) -> str:
    if isinstance(before, str) or isinstance(after, str) or before is None or after is None:
        return "-"
    if round(before, 2) <= 0 or round(after, 2) <= 0:  # nothing measured, or below the printed precision
        return "-"
    return f"{after / before:.2f}x"


def _print_hand(hand: str, before: dict | None, after: dict, args: argparse.Namespace) -> None:
    print(f"\n## {hand}: one unit, {args.approaches} approaches, seed {args.seed}, up to {args.validate} shake-tested "
          "(CPU time unless marked wall)")
    for label, r in (("before", before), ("after", after)):
        if r is not None and "error" in r:
            print(f"{label}: error: {r['error']}")
    b, a = (_figures(before) if before is not None else None), _figures(after)
    keys = list(a) + [k for k in (b or {}) if k not in a]
    if before is None:
        print(f"{'measure':28s} {'after':>10s}")
        for k in keys:
            print(f"{k:28s} {_cell(a.get(k))}")
    else:
        print(f"{'measure':28s} {'before':>10s} {'after':>10s} {'after/before':>13s}")
        for k in keys:
            print(f"{k:28s} {_cell(b.get(k))} {_cell(a.get(k))} {_ratio(b.get(k), a.get(k)):>13s}")
    for label, r in (("before", before), ("after", after)):
        if r is not None and "error" not in r:
            print(f"rejected, {label}: {dict(sorted(r['rejected'].items()))}")


def hand_parser(doc: str | None) -> argparse.ArgumentParser:
    """The options the per-hand benchmarks share: object, hands, approaches, seed."""
    parser = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--object", default="mug")
    parser.add_argument("--hand", action="append", help="hand name (repeat); default: every hand")
    parser.add_argument("--approaches", type=int, default=24)
    parser.add_argument("--seed", type=int, default=0)
    return parser


def _git(*cmd: str) -> str:
    return subprocess.run(["git", "-C", str(ROOT), *cmd], capture_output=True, text=True, check=True).stdout.strip()


def main() -> None:
    parser = hand_parser(__doc__)
    parser.add_argument("--validate", type=int, default=40, help="grasps to shake-test per hand (0: none)")
    parser.add_argument("--before", default=BEFORE, help=f"git commit to compare against (default {BEFORE}; 'none')")
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--json-out", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args)
        return
    if Path(args.object).exists():  # an object file: the children run in their trees
        args.object = str(Path(args.object).resolve())
    if not args.hand:
        sys.path.insert(0, str(ROOT))
        from planner.specs.hands import hand_names

        args.hand = list(hand_names())
    before_rev = None if args.before.lower() == "none" else _git("rev-parse", "--short", args.before)
    head = _git("rev-parse", "--short", "HEAD")
    changed = _git("status", "--porcelain", "--", "planner", "hands", "preshapes", "objects")
    dirty = " + uncommitted changes" if changed else ""
    print(f"# throughput on '{args.object}', {args.approaches} approaches, seed {args.seed}, "
          f"--validate {args.validate}; before {before_rev or '-'}, after {ROOT} ({head}{dirty})")
    print(f"# one child process per side, one core each; {platform.processor() or platform.machine()} "
          f"({platform.machine()}), {os.cpu_count()} cores, Python {platform.python_version()}")
    print(f"# {time.strftime('%Y-%m-%d %H:%M')} start: {uptime()}")
    cache = Path(os.environ.get("GRASP_CACHE", tempfile.gettempdir())) / "throughput"
    with tempfile.TemporaryDirectory() as tmp:
        before = None
        if before_rev is not None:
            before = _side(unpack(before_rev, Path(tmp)), cache / "before", args, Path(tmp) / "before.json")
        after = _side(ROOT, cache / "after", args, Path(tmp) / "after.json")
    print(f"# end: {uptime()}")
    for label, d in (("before", before), ("after", after)):
        if d is not None:
            print(f"# {label}: child wall {d['wall']:.1f} s (object check and convex parts, outside the figures: "
                  f"CPU {d['warm']['cpu']:.1f} s); CPU clocks in {', '.join(d['clocks']) or 'no module'}")
    for hand in args.hand:
        _print_hand(hand, before["hands"][hand] if before is not None else None, after["hands"][hand], args)


if __name__ == "__main__":
    main()
