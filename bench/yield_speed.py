"""Good grasps per core-second, before and after issue 16, side by side.

    python bench/yield_speed.py [--before 8c0cfbe] [--object mug] [--hands barrett allegro pr2 panda]
                                [--approaches 8] [--seed 0]

The ``--before`` commit is unpacked with ``git archive`` into a temporary
folder; each side runs in its own child process (one core) with that tree
first on ``PYTHONPATH`` and its own ``GRASP_CACHE`` sub-folder. Two
measurements per side:

1. **Default Panda sweep**: what ``grasp generate OBJECT --hand panda``
   runs (every unit of the object, the hand's default sampler and sweep
   settings, reachability as the defaults say), one unit after another.
   Printed: candidates (generated poses), grasps with contacts (simulated and
   closed), force-closure grasps, their fraction of candidates and of grasps
   with contacts, force-closure grasps and candidates per CPU second,
   reachability CPU milliseconds per grasp it scored and per unit.
2. **Closing per hand**: one unit of surface rays (``--approaches`` rays,
   every preshape, rolls and standoffs, no reachability) per hand, the same
   candidates on both sides: CPU milliseconds per candidate of approach +
   closing and of contact reading.

All times are CPU seconds of the child (``time.process_time``; the stages'
own clocks are switched to it), object preparation excluded (CoACD is
cached per side after its first run). The machine may be shared: CPU time
is the steadier figure, the load average is printed at start and end.
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
import types
from pathlib import Path

from _trees import unpack as _unpack
from _trees import uptime as _load

ROOT = Path(__file__).resolve().parents[1]
#: main before issue 16 (ALGORITHM_VERSION 1).
BEFORE = "8c0cfbe"


# -- child: runs inside one tree ---------------------------------------------------------------
def _cpu_clocks() -> None:
    """Make the stages' timers read CPU time of this process."""
    import planner.plan.closing as closing
    import planner.plan.unit as unit

    clock = types.SimpleNamespace(perf_counter=time.process_time, process_time=time.process_time)
    unit.time = closing.time = clock  # type: ignore[attr-defined]


def _resolved(settings, hand: str):  # type: ignore[no-untyped-def]
    from planner.specs.hands import load_hand

    return settings.resolved(load_hand(hand).sampler) if hasattr(settings, "resolved") else settings


def _run_units(obj: str, hand: str, settings, seed: int) -> dict:  # type: ignore[no-untyped-def]
    from planner.plan.unit import UnitSpec, run_unit

    units = _resolved(settings, hand).chunks()
    totals = {"units": units, "candidates": 0, "with_contacts": 0, "fc": 0, "reach_scored": 0, "cpu": 0.0,
              "rejected": {}}
    timing: dict[str, float] = {}
    for chunk in range(units):
        t0 = time.process_time()
        result = run_unit(UnitSpec(obj, hand, settings, seed, chunk=chunk))
        totals["cpu"] += time.process_time() - t0
        if result.error:
            raise SystemExit(f"{hand} unit {chunk}: {result.error}")
        totals["candidates"] += result.candidates
        totals["with_contacts"] += len(result.grasps)
        totals["fc"] += result.force_closure
        totals["reach_scored"] += sum(g.reachability is not None for g in result.grasps)
        for k, v in result.timing.items():
            timing[k] = timing.get(k, 0.0) + v
        for k, v in result.rejected.items():
            totals["rejected"][k] = totals["rejected"].get(k, 0) + v
    totals["cpu"] -= timing.get("prepare", 0.0)
    totals["timing"] = timing
    return totals


def child(args: argparse.Namespace) -> None:
    import planner
    from planner.plan.sweep import SweepSettings

    _cpu_clocks()
    out = {"planner": str(Path(planner.__file__).parent.parent),
           "default": _run_units(args.object, "panda", SweepSettings(), args.seed), "closing": {}}
    for hand in args.hands:
        rays = SweepSettings(sampler="surface", approaches=args.approaches, chunk=0, reach_placements=0)
        out["closing"][hand] = _run_units(args.object, hand, rays, args.seed)
    print(json.dumps(out))


# -- parent ---------------------------------------------------------------------------------------
def _side(tree: Path, cache: Path, args: argparse.Namespace) -> dict:
    env = dict(os.environ, PYTHONPATH=str(tree), GRASP_CACHE=str(cache))
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", "--object", args.object, "--seed",
           str(args.seed), "--approaches", str(args.approaches), "--hands", *args.hands]
    done = subprocess.run(cmd, env=env, cwd=tree, capture_output=True, text=True)
    if done.returncode:
        raise SystemExit(f"{tree}: {done.stderr.strip().splitlines()[-1] if done.stderr.strip() else done.returncode}")
    data = json.loads(done.stdout.strip().splitlines()[-1])
    if Path(data["planner"]).resolve() != tree.resolve():
        raise SystemExit(f"the child imported planner from {data['planner']}, not {tree}")
    return data


def _ratio(a: float, b: float) -> str:
    return f"{b / a:.1f}x" if a > 0 else "-"


def _print_default(before: dict, after: dict) -> None:
    def rows(d: dict) -> dict[str, float]:
        t = d["timing"]
        reach = t.get("reachability", 0.0)
        return {
            "units": d["units"], "candidates": d["candidates"], "grasps with contacts": d["with_contacts"],
            "force-closure grasps": d["fc"],
            "FC % of candidates": 100 * d["fc"] / max(d["candidates"], 1),
            "FC % of grasps with contacts": 100 * d["fc"] / max(d["with_contacts"], 1),
            "CPU s (preparation excluded)": d["cpu"],
            "FC grasps / CPU s": d["fc"] / d["cpu"], "candidates / CPU s": d["candidates"] / d["cpu"],
            "closing + contacts CPU ms / grasp with contacts":
                1000 * (t.get("closing", 0) + t.get("contacts", 0)) / max(d["with_contacts"], 1),
            "quality CPU ms / grasp with contacts": 1000 * t.get("quality", 0) / max(d["with_contacts"], 1),
            "reachability: grasps scored": d["reach_scored"],
            "reachability CPU ms / grasp scored": 1000 * reach / max(d["reach_scored"], 1),
            "reachability CPU s / unit": reach / d["units"],
        }
    b, a = rows(before), rows(after)
    print(f"\n## Default Panda sweep ('grasp generate {ARGS.object} --hand panda' settings), seed {ARGS.seed}")
    print(f"{'measure':48s} {'before':>10s} {'after':>10s} {'after/before':>12s}")
    for k in b:
        fmt = "{:10d}" if isinstance(b[k], int) else "{:10.2f}"
        print(f"{k:48s} {fmt.format(b[k])} {fmt.format(a[k])} {_ratio(b[k], a[k]):>12s}")
    print(f"rejected before simulation / in closing, after: {after['rejected']}")


def _print_closing(before: dict, after: dict) -> None:
    print(f"\n## Closing per hand: one unit of {ARGS.approaches} surface rays, no reachability (CPU ms per candidate)")
    print(f"{'hand':8s} {'cand':>5s} | {'closing b':>9s} {'after':>7s} {'x':>5s} | {'contacts b':>10s} {'after':>6s} | "
          f"{'cand/s b':>8s} {'after':>6s} | {'FC b':>4s} {'after':>5s}")
    for hand in before:
        b, a = before[hand], after[hand]
        cb, ca = (1000 * d["timing"].get("closing", 0) / max(d["candidates"], 1) for d in (b, a))
        kb, ka = (1000 * d["timing"].get("contacts", 0) / max(d["candidates"], 1) for d in (b, a))
        print(f"{hand:8s} {b['candidates']:5d} | {cb:9.2f} {ca:7.2f} {_ratio(ca, cb):>5s} | {kb:10.2f} {ka:6.2f} | "
              f"{b['candidates'] / b['cpu']:8.1f} {a['candidates'] / a['cpu']:6.1f} | {b['fc']:4d} {a['fc']:5d}")


ARGS = argparse.Namespace()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--before", default=BEFORE, help="git commit to compare against")
    parser.add_argument("--object", default="mug")
    parser.add_argument("--hands", nargs="+", default=["barrett", "allegro", "pr2", "panda"])
    parser.add_argument("--approaches", type=int, default=8, help="surface rays per hand for the closing figures")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args)
        return
    ARGS.__dict__.update(vars(args))
    print(f"# yield and speed, before {args.before} / after {ROOT.name} "
          f"({platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()})")
    print(f"# {time.strftime('%Y-%m-%d %H:%M')} start: {_load()}")
    cache = Path(os.environ.get("GRASP_CACHE", tempfile.gettempdir())) / "yield_speed"
    with tempfile.TemporaryDirectory() as tmp:
        before = _side(_unpack(args.before, Path(tmp)), cache / "before", args)
        after = _side(ROOT, cache / "after", args)
    print(f"# end: {_load()}")
    _print_default(before["default"], after["default"])
    _print_closing(before["closing"], after["closing"])


if __name__ == "__main__":
    main()
