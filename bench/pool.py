"""The worker pool's costs and how fast a killed run's processes go.

    python bench/pool.py [--repeat 3] [--no-ray]

- start-up: seconds from the pool's start to the first result of a unit
  that needs the planner's imports (``forkserver`` imports them once in the
  fork server; ``spawn`` in every worker), each in a fresh driver process;
- replacement: seconds from a worker's death to its unit running again;
- per unit: pool overhead per trivial unit (2 workers, 2,000 units);
- "before": the same for the pool this one replaced (fork-started
  ``ProcessPoolExecutor``, rebuilt after a worker's death);
- gone after kill -9: ``grasp generate`` (2 workers, or ``--ray``) is
  SIGKILLed once its first unit is in the database; seconds until every
  process below it is gone (polled every 20 ms; zombies count as gone).
  "lifeline": without PR_SET_PDEATHSIG (what other systems get): workers
  notice the driver's death in a watcher thread, which needs the GIL.

Medians of ``--repeat`` runs (min-max). Other jobs may share the machine:
the figures are noisy; compare within one run.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import signal
import sqlite3
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from planner.run import pool, procs  # noqa: E402

KILL_BATCH = ["box", "sphere", "--hand", "panda", "--approaches", "8", "--rolls", "2", "--preshapes", "wide",
              "--chunk", "1", "--reach-placements", "1", "--quiet", "--workers", "2"]
#: [s] the longest a killed run's process is waited for.
CAP = 120.0


def probe(method: str) -> None:
    """In a fresh process: start-up, replacement, per-unit overhead of one method."""
    import _pool_units as units

    start = time.perf_counter()
    results = pool.run(units.with_planner, range(2), 2, start_method=method)
    next(results)
    first = time.perf_counter() - start
    list(results)
    with tempfile.TemporaryDirectory() as tmp:
        [(_, replaced, _)] = pool.run(units.crash_once, [str(Path(tmp) / "mark")], 2, start_method=method)
    n = 2000
    results = pool.run(units.square, range(n), 2, start_method=method)
    next(results)
    t = time.perf_counter()
    assert sum(1 for _ in results) == n - 1
    per_unit = (time.perf_counter() - t) / (n - 1)
    print(f"{first} {replaced} {per_unit}")


def probe_before() -> None:
    """The same for the pool this one replaced (main 8c0cfbe): a fork-started
    ``ProcessPoolExecutor``, at most ``workers`` units in flight. Replacement
    is the rebuild of the whole executor after ``BrokenProcessPool``."""
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    import _pool_units as units

    def run(fn, todo: list, workers: int = 2):  # type: ignore[no-untyped-def]
        todo = list(reversed(todo))
        while todo:
            with ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("fork")) as ex:
                flight: dict = {}
                while todo or flight:
                    while todo and len(flight) < workers:
                        unit = todo.pop()
                        flight[ex.submit(fn, unit)] = unit
                    done, _ = wait(flight, return_when=FIRST_COMPLETED)
                    try:
                        for fut in done:
                            unit = flight.pop(fut)
                            yield fut.result()
                    except BrokenProcessPool:
                        todo.append(unit)
                        todo.extend(flight.values())
                        break

    start = time.perf_counter()
    results = run(units.with_planner, list(range(2)))
    next(results)
    first = time.perf_counter() - start
    list(results)
    with tempfile.TemporaryDirectory() as tmp:
        [replaced] = run(units.crash_once, [str(Path(tmp) / "mark")])
    n = 2000
    results = run(units.square, list(range(n)))
    next(results)
    t = time.perf_counter()
    assert sum(1 for _ in results) == n - 1
    print(f"{first} {replaced} {(time.perf_counter() - t) / (n - 1)}")


def killed_driver(db: Path, ray: bool, method: str, pdeathsig: bool = True) -> tuple[float, int]:
    """(seconds until the tree of a killed ``grasp generate`` is gone, its size)."""
    code = ("import sys\nfrom planner.run import pool\npool.START_METHOD = sys.argv[1]\n"
            f"pool.USE_PDEATHSIG = {pdeathsig}\nfrom planner.cli import main\nsys.exit(main(sys.argv[2:]))")
    argv = [sys.executable, "-c", code, method, "generate", *KILL_BATCH, "--db", str(db), *(["--ray"] if ray else [])]
    driver = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    left: dict[int, int | None] = {}
    try:
        while not _units(db):
            if driver.poll() is not None:
                raise RuntimeError("the run ended before its first unit")
            time.sleep(0.02)
        left = {p: procs.start_ticks(p) for p in procs.descendants(driver.pid)}
        driver.send_signal(signal.SIGKILL)
        driver.wait()
        start = time.monotonic()
        while any(procs.alive(p, t) for p, t in left.items()):
            if time.monotonic() - start > CAP:
                return float("inf"), len(left)
            time.sleep(0.02)
        return time.monotonic() - start, len(left)
    finally:
        driver.kill()
        driver.wait()
        for p, t in left.items():
            if procs.alive(p, t):
                os.kill(p, signal.SIGKILL)


def _units(db: Path) -> int:
    try:
        with sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=5) as conn:
            return conn.execute("SELECT COUNT(*) FROM units").fetchone()[0]
    except sqlite3.Error:
        return 0


def spread(values: list[float], scale: float = 1.0, digits: int = 2) -> str:
    v = [x * scale for x in values]
    return f"{statistics.median(v):.{digits}f} ({min(v):.{digits}f}-{max(v):.{digits}f})"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--no-ray", action="store_true")
    ap.add_argument("--probe", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.probe:
        probe_before() if args.probe == "before" else probe(args.probe)
        return
    print(f"# {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} at the start, "
          f"medians of {args.repeat} runs (min-max)")
    print(f"{'start method':12s} {'start-up [s]':>18s} {'replacement [s]':>18s} {'per unit [us]':>16s}")
    for method in [*pool.START_METHODS, "before"]:
        rows = [[float(x) for x in subprocess.run([sys.executable, __file__, "--probe", method], check=True,
                                                  capture_output=True, text=True).stdout.split()]
                for _ in range(args.repeat)]
        print(f"{method:12s} {spread([r[0] for r in rows]):>18s} {spread([r[1] for r in rows]):>18s} "
              f"{spread([r[2] for r in rows], 1e6, 0):>16s}")
    cases = [(f"pool, {m}", False, m, True) for m in pool.START_METHODS]
    cases += [("pool, forkserver, lifeline", False, "forkserver", False)]  # no PR_SET_PDEATHSIG anywhere
    cases += [] if args.no_ray else [("Ray, local", True, pool.START_METHOD, True)]
    print(f"\n{'grasp generate killed (-9)':28s} {'all gone after [s]':>22s} {'processes':>10s}")
    for label, ray, method, pdeathsig in cases:
        runs = []
        for _ in range(args.repeat):
            with tempfile.TemporaryDirectory() as tmp:
                runs.append(killed_driver(Path(tmp) / "k.db", ray, method, pdeathsig))
        print(f"{label:28s} {spread([r[0] for r in runs], digits=3):>22s} {max(r[1] for r in runs):>10d}")


if __name__ == "__main__":
    main()
