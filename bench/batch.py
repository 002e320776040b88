"""Batch generation at scale: what a 1,000-object database costs with the
default sweep and a simulated label on every grasp that ranks first (force
closure as planned or once squeezed), and how the backends scale.

    python bench/batch.py [--objects 50] [--scaling-objects 8] [--hand panda] [--workers 2] [--no-scaling]
                          [--tree REV]

1. **The 1,000-object extrapolation** (``--objects`` of ``builtin:random``,
   the hand's default sweep exactly as ``grasp generate`` runs it: its
   sampler, the force-closure budget, reachability): ``grasp generate`` with
   ``--workers`` processes, then ``grasp validate --all --force-closure
   --robust 0`` (one trial per grasp force closure as planned or once
   squeezed) with as many.
   Printed: wall seconds of each, objects, grasps and force-closure grasps,
   the units' own seconds (CPU of the workers), trials per second, and the
   wall time 1,000 such objects would take (the per-object wall time times
   1,000: ``random_NNN`` objects are drawn from one distribution).
2. **Scaling** (the first ``--scaling-objects`` of them, the same default
   sweep): one process, the process pool with ``--workers`` processes, and
   a private local Ray instance with ``--workers`` CPUs, each building its
   own database from scratch; the script checks that the three store
   identical grasps and prints each one's speed-up over one process and its
   efficiency (speed-up / workers).

``--tree REV`` (a commit, branch or tag) runs the whole benchmark from that
commit, unpacked with ``git archive`` into a temporary folder (the script
starts itself again with the folder first on ``PYTHONPATH``; the pool's and
Ray's workers inherit it): a run of half an hour imports modules lazily, so
it must not read a checkout that is being edited meanwhile.

Wall clock throughout (the pool's workers are processes of their own); the
load average is printed at start and end: the figures mean something only
on an otherwise idle machine.
"""

from __future__ import annotations

import argparse
import os
import platform
import sqlite3
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _trees import unpack

from planner import api
from planner.plan.sweep import SweepSettings


def content(db: Path) -> list[tuple]:
    with sqlite3.connect(db) as conn:
        return conn.execute("SELECT object, candidate, pose, epsilon, score FROM grasps ORDER BY object, candidate"
                            ).fetchall()


def unit_seconds(db: Path) -> float:
    with sqlite3.connect(db) as conn:
        return float(conn.execute("SELECT COALESCE(SUM(seconds), 0) FROM units").fetchone()[0])


def load() -> str:
    return os.popen("uptime").read().strip()


def extrapolation(names: list[str], count: int, hand: str, workers: int, folder: Path) -> None:
    db = folder / "batch.db"
    t0 = time.perf_counter()
    summary = api.generate(names, hand, db_path=db, settings=SweepSettings(), seed=0, workers=workers)
    sweep = time.perf_counter() - t0
    if summary.failed:
        print(f"failed objects: {summary.failed}")
    t1 = time.perf_counter()
    checked = api.validate(db, every=True, closure_only=True, robust_samples=0, workers=workers)
    trials = time.perf_counter() - t1
    per_object = (sweep + trials) / count
    print(f"## default sweep of {count} objects, {hand}, {workers} worker processes")
    print(f"sweep: {sweep:.1f} s wall, units' own time {unit_seconds(db):.1f} s; {summary.candidates} candidates, "
          f"{summary.grasps} grasps with contacts, {summary.force_closure} force-closure "
          f"({summary.force_closure / count:.0f} per object), rejected {dict(summary.rejected)}")
    print(f"validation of every grasp force closure as planned or once squeezed: {trials:.1f} s wall, "
          f"{checked.grasps} trials "
          f"({checked.grasps / trials:.1f} per s on {workers} processes), {checked.successes} held, "
          f"failed tasks {len(checked.failed_tasks)}")
    print(f"per object: sweep {sweep / count:.1f} s + validation {trials / count:.1f} s wall")
    print(f"extrapolated 1,000 objects: sweep {1000 * sweep / count / 3600:.2f} h + validation "
          f"{1000 * trials / count / 3600:.2f} h = {1000 * per_object / 3600:.2f} h on this machine")


def scaling(names: list[str], count: int, hand: str, workers: int) -> None:
    runs = [("1 process", dict(workers=1)), (f"{workers} worker processes", dict(workers=workers)),
            (f"Ray local, {workers} CPUs", dict(workers=workers, use_ray=True))]
    print(f"## scaling: default sweep of {count} objects, {hand}")
    print(f"{'backend':24s} {'seconds':>8s} {'objects/h':>10s} {'FC/s':>7s} {'speed-up':>9s} {'efficiency':>10s}")
    base, reference = None, None
    for label, kwargs in runs:
        with tempfile.TemporaryDirectory() as tmp:
            db = Path(tmp) / "b.db"
            t = time.perf_counter()
            summary = api.generate(names, hand, db_path=db, settings=SweepSettings(), seed=0, **kwargs)
            dt = time.perf_counter() - t
            got = content(db)
        reference = reference if reference is not None else got
        base = base or dt
        print(f"{label:24s} {dt:8.1f} {3600 * count / dt:10.0f} {summary.force_closure / dt:7.1f} "
              f"{base / dt:8.2f}x {base / (dt * kwargs['workers']):10.0%}"
              f"{'' if got == reference else '  (DIFFERENT GRASPS!)'}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--objects", type=int, default=50)
    parser.add_argument("--scaling-objects", type=int, default=8)
    parser.add_argument("--hand", default="panda")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--no-scaling", action="store_true")
    parser.add_argument("--tree", help="run from this commit (git archive into a temporary folder)")
    args = parser.parse_args()
    if args.tree:
        with tempfile.TemporaryDirectory() as tmp:
            tree = unpack(args.tree, Path(tmp))
            path = os.pathsep.join([str(tree), *filter(None, [os.environ.get("PYTHONPATH")])])
            env = dict(os.environ, PYTHONPATH=path, GRASP_HOME=str(tree))
            again = ["--objects", str(args.objects), "--scaling-objects", str(args.scaling_objects), "--hand",
                     args.hand, "--workers", str(args.workers), *(["--no-scaling"] if args.no_scaling else [])]
            print(f"# tree {args.tree} unpacked into {tree}", flush=True)
            sys.exit(subprocess.run([sys.executable, str(tree / "bench" / "batch.py"), *again], env=env,
                                    cwd=tree).returncode)
    print(f"# planner imported from {Path(api.__file__).resolve().parents[2]}")
    print(f"# {time.strftime('%Y-%m-%d %H:%M')}, {platform.machine()}, {os.cpu_count()} cores, "
          f"Python {platform.python_version()}")
    print(f"# start: {load()}")
    with tempfile.TemporaryDirectory() as tmp:
        extrapolation([f"builtin:random:{args.objects}"], args.objects, args.hand, args.workers, Path(tmp))
    print(f"# {load()}")
    if not args.no_scaling:
        scaling([f"builtin:random:{args.scaling_objects}"], args.scaling_objects, args.hand, args.workers)
    print(f"# end: {load()}")


if __name__ == "__main__":
    main()
