"""Export throughput: grasps per second per format on a >= 100,000-grasp database.

    python bench/export.py [--grasps 100000] [--per-object 2000] [--workdir DIR] [--format csv ...]

The database is built quickly and kept in ``--workdir`` (default: a folder
under the system temp dir) for reuse:

1. a real small database: ``box``, ``sphere`` and ``cylinder`` for the
   Panda (24 approaches, 2 rolls, both preshapes, no reachability);
2. replicated in SQL: each object is copied under new names
   (``box_c000``, ...) with its own ``objects`` row and a copy of its unit;
   each copy gets the source grasps ``INSERT ... SELECT``-ed several times
   with candidate numbers shifted by 1,000,000 per repeat, until a copy
   holds about ``--per-object`` grasps (ACRONYM has 2,000 per object) and the
   database at least ``--grasps``; every 10th grasp gets a validation and a
   robust row (so the joins do real work); then every copy is re-ranked.

Each format is exported in a fresh child process (one core), which reports
its wall time and peak resident memory; the parent adds the child's CPU time
(user + system, imports included: the figure to compare on a shared machine,
where wall time moves with the load); the output files are then deleted.
"""

from __future__ import annotations

import argparse
import json
import platform
import resource
import shutil
import sqlite3
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SOURCES = ("box", "sphere", "cylinder")
FORMATS = ("acronym", "graspgen", "dexgraspnet", "parquet", "csv")
SHIFT = 1_000_000
GRASP_COLUMNS = ("preshape, candidate, approach_point, approach_dir, roll, standoff, pose, open_joints, closed_joints,"
                 " width, contacts, n_contacts, links_touching, epsilon, volume, force_closure, reachability,"
                 " manipulability, seed, score")


def build(path: Path, grasps: int, per_object: int) -> int:
    """The benchmark database at ``path`` (reused if it already has enough grasps)."""
    if path.exists():
        with sqlite3.connect(path) as conn:
            count = conn.execute("SELECT COUNT(*) FROM grasps").fetchone()[0]
        if count >= grasps:
            return count
        path.unlink()
    from planner import api
    from planner.plan.sweep import SweepSettings

    settings = SweepSettings(approaches=24, rolls=2, reach_placements=0)
    summary = api.generate(list(SOURCES), "panda", db_path=path, settings=settings, workers=1)
    if summary.failed:
        raise SystemExit(f"generate failed: {summary.failed}")
    from planner.db.store import open_db

    conn = sqlite3.connect(path, isolation_level=None)
    units = conn.execute("SELECT id, object, (SELECT COUNT(*) FROM grasps g WHERE g.unit_id = u.id) FROM units u"
                         " ORDER BY object").fetchall()
    total = sum(n for _, _, n in units)
    copy = 0
    conn.execute("BEGIN")
    while total < grasps:
        for unit_id, obj, n in units:
            name = f"{obj}_c{copy:03d}"
            repeats = max(1, round(per_object / n))
            conn.execute("INSERT INTO objects SELECT ?, source, scale, mesh_sha256, mass, friction, density, volume,"
                         " com, inertia, torque_scale, extents FROM objects WHERE name = ?", (name, obj))
            new_unit = conn.execute(
                "INSERT INTO units (object, hand, settings_hash, seed, chunk, settings, status, candidates, grasps,"
                " force_closure) SELECT ?, hand, settings_hash, seed, chunk, settings, status, candidates * ?,"
                " grasps * ?, force_closure * ? FROM units WHERE id = ?",
                (name, repeats, repeats, repeats, unit_id)).lastrowid
            conn.execute(
                f"WITH RECURSIVE r(k) AS (SELECT 0 UNION ALL SELECT k + 1 FROM r WHERE k < ? - 1)"
                f" INSERT INTO grasps (unit_id, object, hand, {GRASP_COLUMNS})"
                f" SELECT ?, ?, hand, {GRASP_COLUMNS.replace('candidate', f'candidate + r.k * {SHIFT}')}"
                f" FROM grasps, r WHERE unit_id = ? ORDER BY r.k, id", (repeats, new_unit, name, unit_id))
            total += n * repeats
        copy += 1
    conn.execute("INSERT INTO validation (grasp_id, success, fingers_in_contact, closing_linear, closing_angular,"
                 " shaking_linear, shaking_angular, seed, settings)"
                 " SELECT id, id % 2, 2, 0.001, 0.01, 0.002, 0.02, 0, '{}' FROM grasps WHERE id % 10 = 0")
    conn.execute("INSERT INTO robust SELECT id, epsilon * 0.8, epsilon * 0.5, 25, 0, '{}' FROM grasps"
                 " WHERE id % 10 = 0")
    conn.execute("COMMIT")
    conn.close()
    with open_db(path) as db:  # rank every copy as the database would
        db.apply_rule(db.rule(), force=True)
    return total


def child(db: Path, fmt: str, out: Path) -> None:
    """Run one export in this process; print a JSON line."""
    from planner.datasets.exporter import export

    start = time.perf_counter()
    summary = export(db, fmt, out)
    seconds = time.perf_counter() - start
    size = sum(p.stat().st_size for p in summary.files)
    print(json.dumps({"format": fmt, "grasps": summary.grasps, "files": len(summary.files), "seconds": seconds,
                      "bytes": size, "peak_mb": peak_rss_mb()}))


def peak_rss_mb() -> float:
    """This process's peak resident memory. Not ``ru_maxrss``: Linux carries
    that over from the parent across fork + exec."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def child_cpu_seconds() -> float:
    """User + system CPU time of this process's finished children."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--grasps", type=int, default=100_000)
    parser.add_argument("--per-object", type=int, default=2000)
    parser.add_argument("--workdir", type=Path, default=Path(tempfile.gettempdir()) / "grasp-bench-export")
    parser.add_argument("--format", action="append", choices=FORMATS)
    parser.add_argument("--child", nargs=3, metavar=("DB", "FORMAT", "OUT"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(Path(args.child[0]), args.child[1], Path(args.child[2]))
        return
    args.workdir.mkdir(parents=True, exist_ok=True)
    db = args.workdir / "bench.db"
    t0 = time.perf_counter()
    total = build(db, args.grasps, args.per_object)
    with sqlite3.connect(db) as conn:
        pairs = conn.execute("SELECT COUNT(DISTINCT object) FROM grasps").fetchone()[0]
    print(f"# export benchmark: {total} grasps, {pairs} objects x panda ({db}, ready in "
          f"{time.perf_counter() - t0:.1f} s); Python {platform.python_version()}, "
          f"{platform.machine()}, one process per format")
    print(f"{'format':12s} {'grasps':>7s} {'files':>5s} {'seconds':>8s} {'grasps/s':>9s} {'CPU s':>6s} "
          f"{'MB out':>7s} {'peak RSS MB':>11s}")
    for fmt in args.format or FORMATS:
        out = args.workdir / f"out-{fmt}"
        shutil.rmtree(out, ignore_errors=True)
        before = child_cpu_seconds()
        run = subprocess.run([sys.executable, __file__, "--child", str(db), fmt, str(out)], capture_output=True,
                             text=True, check=False)
        cpu = child_cpu_seconds() - before
        shutil.rmtree(out, ignore_errors=True)
        if run.returncode:
            raise SystemExit(f"{fmt}: {run.stderr.strip()}")
        r = json.loads(run.stdout.strip().splitlines()[-1])
        print(f"{fmt:12s} {r['grasps']:7d} {r['files']:5d} {r['seconds']:8.2f} {r['grasps'] / r['seconds']:9.0f} "
              f"{cpu:6.2f} {r['bytes'] / 1e6:7.1f} {r['peak_mb']:11.0f}")


if __name__ == "__main__":
    main()
