"""Start-up time of the ``grasp`` command (issue 25 item 8).

Prints, for ``grasp --help`` and ``grasp best`` on a small database, the
median wall time of ``--runs`` fresh interpreters (each a subprocess, as a
user's shell starts it), and the heaviest imports of ``import planner.cli``
by ``python -X importtime`` (cumulative microseconds, top ``--top``).

``--root DIR`` runs another checkout's code (e.g. the branch's first commit,
unpacked with ``git archive COMMIT | tar -x -C DIR``); ``--compare DIR``
runs both and prints them side by side. The database is built once per root
with the root's own code (a box, 20 surface points, one worker) unless
``--db`` names one.

    python bench/startup.py --runs 7 --compare /tmp/startup-base
"""

from __future__ import annotations

import argparse
import math
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent.parent
#: Every run is a fresh interpreter with the project's code first on the path.
CLI = ("-m", "planner.cli")


def env_for(root: Path) -> dict[str, str]:
    """``root``'s code first (the processes also run in ``root``: ``-m`` and ``-c`` put the working folder first)."""
    return {**os.environ, "PYTHONPATH": str(root)}


def timed(root: Path, args: list[str], runs: int) -> tuple[float, float]:
    """Median wall time and median CPU time (user + system) [s] of ``python -m
    planner.cli ARGS`` over ``runs`` fresh processes. On a loaded machine the
    wall time grows with the load; the CPU time much less."""
    walls, cpus = [], []
    for _ in range(runs):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        start = time.perf_counter()
        done = subprocess.run([sys.executable, *CLI, *args], env=env_for(root), cwd=root, capture_output=True,
                              text=True)
        walls.append(time.perf_counter() - start)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpus.append(after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime)
        if done.returncode != 0:
            raise SystemExit(f"{root}: grasp {' '.join(args)} failed ({done.returncode}): {done.stderr.strip()}")
    return statistics.median(walls), statistics.median(cpus)


def small_db(root: Path, folder: Path) -> Path:
    path = folder / f"startup-{abs(hash(str(root)))}.db"
    if not path.is_file():
        subprocess.run([sys.executable, *CLI, "generate", "box", "--hand", "panda", "--db", str(path),
                        "--approaches", "20", "--workers", "1", "--quiet", "--reach-placements", "0"],
                       env=env_for(root), cwd=root, check=True, capture_output=True)
    return path


def import_times(root: Path) -> dict[str, int]:
    """Cumulative import time [us] of each module ``import planner.cli`` imports."""
    done = subprocess.run([sys.executable, "-X", "importtime", "-c", "import planner.cli"], env=env_for(root),
                          cwd=root, capture_output=True, text=True, check=True)
    out = {}
    for line in done.stderr.splitlines():
        m = re.match(r"import time:\s+(\d+) \|\s+(\d+) \|(\s*)(\S+)", line)
        if m:
            out[m.group(4)] = int(m.group(2))
    return out


def measure(root: Path, runs: int, db: Path | None, folder: Path) -> dict:
    where = subprocess.run([sys.executable, "-c", "import planner; print(planner.__file__)"], env=env_for(root),
                           cwd=root, capture_output=True, text=True, check=True).stdout.strip()
    if not Path(where).resolve().is_relative_to(root):
        raise SystemExit(f"{root}: the processes import planner from {where}, not from this checkout")
    path = db or small_db(root, folder)
    return {"help": timed(root, ["--help"], runs),
            "best": timed(root, ["best", "box", "--hand", "panda", "--db", str(path)], runs),
            "imports": import_times(root)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=7)
    parser.add_argument("--top", type=int, default=15)
    parser.add_argument("--root", type=Path, default=HERE)
    parser.add_argument("--compare", type=Path, help="another checkout, shown as 'before'")
    parser.add_argument("--db", type=Path)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        now = measure(args.root.resolve(), args.runs, args.db, Path(tmp))
        before = measure(args.compare.resolve(), args.runs, args.db, Path(tmp)) if args.compare else None
    print(f"median of {args.runs} fresh processes, {os.cpu_count()} cores, load {os.getloadavg()[0]:.2f}")
    print(f"{'':18s} {'wall before':>12s} {'wall now':>9s} {'CPU before':>11s} {'CPU now':>8s}")
    for key, label in (("help", "grasp --help [s]"), ("best", "grasp best [s]")):
        old = before[key] if before else (math.nan, math.nan)
        print(f"{label:18s} {old[0]:12.3f} {now[key][0]:9.3f} {old[1]:11.3f} {now[key][1]:8.3f}")
    print(f"\nimport planner.cli, cumulative [ms] (top {args.top} of now, and before):")
    heavy = ("trimesh", "pybullet", "h5py", "pyarrow", "matplotlib", "scipy", "yourdfpy", "rich", "numpy",
             "planner.api", "planner.datasets.exporter", "planner.cli")
    names = sorted(now["imports"], key=now["imports"].get, reverse=True)[:args.top]
    for name in dict.fromkeys([*names, *heavy]):
        old = before["imports"].get(name) if before else None
        new = now["imports"].get(name)
        if old is None and new is None:
            continue
        fmt = lambda v: f"{v / 1000:8.1f}" if v is not None else f"{'-':>8s}"  # noqa: E731
        print(f"  {name:40s} {fmt(old)} {fmt(new)}")


if __name__ == "__main__":
    main()
