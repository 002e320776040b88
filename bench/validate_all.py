"""CPU per trial of ``grasp validate --all --force-closure --robust 0`` as ``bench/batch.py`` runs it (issue 24:
the batch's second part), trial and everything around it: the workers' tasks, the driver's writes and re-scoring.

    python bench/validate_all.py [--objects random_002 random_007 random_011] [--workers 2] [--rounds 3]
                                 [--tree REV] [--against REV] [--db FILE]

A database of the Panda's default sweep of ``--objects`` (tuning objects of bench/calibration_split.toml only) is
made once (``--db``, default ``out/validate_all.db``). Then, ``--rounds`` times and each tree in turn (this
checkout or ``--tree REV``, and ``--against REV``, each unpacked with ``git archive``), one child process
validates a copy of it with ``--workers`` processes (1: in the child). Printed per run: trials, CPU of the child
(the driver) and of its pool's workers (the fork server's children, reaped: ``/proc/PID/stat``; the fork server's
own imports included), CPU per trial, and whether every table but ``meta`` and ``units`` is the same row for row
by ``repr`` as the first tree's first run. CPU time, not wall time: the machine may be shared (the load is printed).
"""

from __future__ import annotations

import argparse
import os
import shutil
import sqlite3
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import tomllib
from _trees import ROOT, unpack, uptime

SPLIT = Path(__file__).with_name("calibration_split.toml")


def fork_server_cpu() -> float:
    """[s] CPU of this process's fork server and its reaped children (the pool's workers); 0 without one."""
    from multiprocessing import forkserver

    pid = getattr(forkserver._forkserver, "_forkserver_pid", None)
    if not pid:
        return 0.0
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return sum(int(v) for v in fields[11:15]) / os.sysconf("SC_CLK_TCK")  # utime stime cutime cstime


def dump(db: Path, out: Path) -> None:
    with sqlite3.connect(db) as conn, out.open("w") as f:
        for (table,) in conn.execute("SELECT name FROM sqlite_master WHERE type = 'table' ORDER BY name"):
            if table not in ("meta", "units"):
                for row in conn.execute(f"SELECT * FROM {table} ORDER BY rowid"):
                    f.write(f"{table} {row!r}\n")


def child(db: Path, workers: int, out: Path) -> None:
    from planner import api

    with tempfile.TemporaryDirectory() as tmp:
        copy = Path(tmp) / "v.db"
        shutil.copy(db, copy)
        start = time.process_time()
        summary = api.validate(copy, every=True, closure_only=True, robust_samples=0, workers=workers)
        driver = time.process_time() - start
        pool = fork_server_cpu()
        dump(copy, out)
    n = max(summary.grasps, 1)
    print(f"{summary.grasps} trials, {summary.successes} held, {len(summary.failed_tasks)} failed tasks; driver "
          f"{driver:.2f} s + workers {pool:.2f} s CPU: {(driver + pool) / n * 1e3:.3f} ms a trial "
          f"(driver {driver / n * 1e3:.3f})", flush=True)


def database(path: Path, objects: list[str]) -> None:
    split = tomllib.loads(SPLIT.read_text())
    held = {name for key, names in split.items() if key.startswith("held_out") for name in names}
    bad = [o for o in objects if o in held or o not in split["tuning"]]
    if bad:
        raise SystemExit(f"not tuning objects (see {SPLIT}): {', '.join(bad)}")
    if path.exists():
        return
    from planner import api
    from planner.plan.sweep import SweepSettings

    path.parent.mkdir(parents=True, exist_ok=True)
    api.generate(objects, "panda", db_path=path, settings=SweepSettings(), seed=0, workers=1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--objects", nargs="+", default=["random_002", "random_007", "random_011"])
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--tree", help="run this commit instead of the checkout")
    parser.add_argument("--against", help="a second commit, run alternately with the first")
    parser.add_argument("--db", type=Path, default=Path("out") / "validate_all.db")
    parser.add_argument("--child", type=Path, help=argparse.SUPPRESS)  # run once here, dump to this file
    args = parser.parse_args()
    if args.child:
        child(args.db, args.workers, args.child)
        return
    database(args.db.resolve(), args.objects)
    print(f"# validate --all --force-closure --robust 0 of {', '.join(args.objects)}, {args.workers} workers; "
          f"start: {uptime()}", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for side in ("tree", "against"):
            (folder / side).mkdir()
        trees = [(args.tree or "checkout", unpack(args.tree, folder / "tree") if args.tree else ROOT)]
        if args.against:
            trees.append((args.against, unpack(args.against, folder / "against")))
        first = None
        for round_ in range(args.rounds):
            for label, tree in trees:
                out = folder / f"dump_{label}_{round_}.txt"
                env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tree), *filter(None, [
                    os.environ.get("PYTHONPATH")])]))
                done = subprocess.run([sys.executable, __file__, "--db", str(args.db.resolve()), "--workers",
                                       str(args.workers), "--child", str(out)], env=env, capture_output=True,
                                      text=True)
                if done.returncode:
                    raise SystemExit(done.stderr[-3000:])
                first = first or out
                same = "same rows" if out.read_bytes() == first.read_bytes() else "DIFFERENT ROWS"
                print(f"round {round_ + 1}, {label}: {done.stdout.strip()}; {same}; {uptime()}", flush=True)
    print(f"# end: {uptime()}")


if __name__ == "__main__":
    main()
