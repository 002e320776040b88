"""Benchmark: fast epsilon / evaluate against the plain qhull reference.

    python bench/quality.py [--sets N] [--seed S] [--norm {L1,Linf}]

Contacts lie on a sphere of radius 5 cm (inward normals, random tangent roll),
uniform on a spherical cap around a random axis whose half-angle is uniform
in [45, 180] degrees (180 = the whole sphere), so that every contact count
gets both force-closure and non-closure sets.  Point contacts, 8 cone edges,
mu = 0.5, p = sphere centre, rho = 5 cm.  Each set is timed 3 times and the
best kept; the table shows the median over sets, all measured in this run.

--norm Linf times epsilon(..., norm="Linf") and evaluate(..., norm="Linf")
on the same sets against the brute-force reference (one default qhull of
every Minkowski sum), with fewer counts and repeats (see LINF_*), then the
regression cases of issue 13, each in a child process limited to
CHILD_MEMORY bytes of address space.  The code timed is the ``planner``
found first on sys.path: PYTHONPATH=<other checkout> times another version.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import platform
import resource
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import scipy

# Appended, not prepended: a PYTHONPATH checkout wins (--norm Linf compares versions).
sys.path.append(str(Path(__file__).resolve().parent.parent))
sys.path.append(str(Path(__file__).resolve().parent.parent / "tests" / "quality"))

from quality_support import coplanar_soft_case, soft_sphere_case

import planner
from planner.quality import FORCE_CLOSURE_TOL, epsilon, evaluate, primitive_wrenches, volume
from planner.quality import reference as reference_module
from planner.quality.reference import reference_epsilon, reference_linf_epsilon

RADIUS = 0.05
ARGS = {"mu": 0.5, "center": np.zeros(3), "torque_scale": RADIUS, "cone_edges": 8, "model": "point"}
COUNTS = (3, 4, 8, 16)
REPEATS = 3

LINF_COUNTS = (3, 4, 8)
#: The brute-force reference hulls all 9^n Minkowski sums: 6,561 points at 4
#: contacts, 43 million at 8.
LINF_REFERENCE_MAX = 4
#: evaluate (its volume) enumerates the Minkowski-sum vertices: ~0.6 s at 3
#: point contacts, ~18 s at 4 on an idle machine (54 s under load): 3 only.
LINF_EVALUATE_MAX = 3
LINF_REPEATS = 1
#: Address-space limit of each regression-case child [bytes]: the dense check
#: of the code before issue 13 asks for 31 GiB and must fail, not swap.
CHILD_MEMORY = 8 * 2**30
CHILD_TIMEOUT = 900.0


def frames_from_normals(normals: np.ndarray, roll: np.ndarray) -> np.ndarray:
    helper = np.where(np.abs(normals[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
    tan_l = np.cross(normals, helper)
    tan_l /= np.linalg.norm(tan_l, axis=1, keepdims=True)
    tan_o = np.cross(normals, tan_l)
    c, s = np.cos(roll)[:, None], np.sin(roll)[:, None]
    return np.stack([normals, c * tan_l + s * tan_o, -s * tan_l + c * tan_o], axis=2)


def cap_grasp(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """n contacts uniform on a random cap of the sphere (see module doc)."""
    half_angle = np.radians(rng.uniform(45, 180))
    z = rng.uniform(np.cos(half_angle), 1.0, n)            # uniform area on the cap
    phi = rng.uniform(0, 2 * np.pi, n)
    local = np.stack([np.sqrt(1 - z**2) * np.cos(phi), np.sqrt(1 - z**2) * np.sin(phi), z], 1)
    axes, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    d = local @ axes.T
    return RADIUS * d, frames_from_normals(-d, rng.uniform(0, 2 * np.pi, n))


def best_time(fn: Callable[..., object], *args: object, repeats: int = REPEATS, **kw: object) -> float:
    """Best of ``repeats`` wall-clock times of fn(*args, **ARGS, **kw) [s]."""
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        fn(*args, **ARGS, **kw)
        best = min(best, time.perf_counter() - start)
    return best


def timed(fn: Callable[..., object], *args: object, **kw: object) -> tuple[object, float]:
    """fn(*args, **ARGS, **kw) and the best of LINF_REPEATS wall-clock times [s]
    (the first run counts as one)."""
    start = time.perf_counter()
    value = fn(*args, **ARGS, **kw)
    first = time.perf_counter() - start
    return value, min(first, best_time(fn, *args, repeats=LINF_REPEATS - 1, **kw))


def reference(points: np.ndarray, frames: np.ndarray, **args: object) -> float:
    """The plain path: all primitive wrenches, one default qhull."""
    return reference_epsilon(primitive_wrenches(points, frames, **args).wrenches)


def reference_linf(points: np.ndarray, frames: np.ndarray, **args: object) -> float:
    """The plain L-infinity path: one default qhull of every Minkowski sum."""
    return reference_linf_epsilon(*primitive_wrenches(points, frames, **args))


def error(fast: float, ref: float, closure: bool) -> float:
    """Relative error for closure sets, absolute otherwise (both should be 0)."""
    return abs(fast - ref) / ref if closure else abs(fast - ref)


def l1_row(pts: np.ndarray, frames: np.ndarray, ref: float, closure: bool) -> tuple:
    err = error(epsilon(pts, frames, **ARGS), ref, closure)
    return (best_time(reference, pts, frames), best_time(epsilon, pts, frames),
            best_time(evaluate, pts, frames), err, 0)


def linf_row(pts: np.ndarray, frames: np.ndarray, closure: bool) -> tuple:
    """(reference, epsilon, evaluate) seconds (nan if skipped), the largest
    error of epsilon and evaluate's epsilon vs the reference (nan without
    one), and how many calls raised."""
    count = len(pts)
    has_ref = count <= LINF_REFERENCE_MAX
    ref, ref_s = timed(reference_linf, pts, frames) if has_ref else (np.nan, np.nan)
    calls = [(epsilon, lambda v: v)]
    if count <= LINF_EVALUATE_MAX:
        calls.append((evaluate, lambda q: q.epsilon))
    times, errs, raised = [], [], 0
    for fn, eps_of in calls:
        try:
            value, seconds = timed(fn, pts, frames, norm="Linf")
            times.append(seconds)
            errs.append(error(eps_of(value), ref, closure) if has_ref else np.nan)
        except Exception:                   # HullError after issue 13, anything before
            times.append(np.nan)
            raised += 1
    times += [np.nan] * (2 - len(times))
    return (ref_s, *times, max(errs, default=np.nan), raised)


def run(count: int, sets: int, rng: np.random.Generator, norm: str) -> dict[bool, list[tuple]]:
    """Per class (closure or not): (reference, epsilon, evaluate) seconds,
    max error and calls that raised."""
    rows: dict[bool, list[tuple]] = {True: [], False: []}
    for _ in range(200 * sets):
        if min(len(v) for v in rows.values()) >= sets:
            break
        pts, frames = cap_grasp(rng, count)
        ref = reference(pts, frames, **ARGS)
        closure = ref > FORCE_CLOSURE_TOL
        if len(rows[closure]) >= sets:
            continue
        rows[closure].append(l1_row(pts, frames, ref, closure) if norm == "L1"
                             else linf_row(pts, frames, closure))
    return rows


def cell(ms: float, fmt: str = ".2f") -> str:
    return "—" if np.isnan(ms) else format(ms, fmt)


def print_table(counts: tuple[int, ...], sets_of: Callable[[int], int], rng: np.random.Generator,
                norm: str) -> None:
    print("| contacts | class | sets | reference ms | epsilon ms | speed-up | evaluate ms "
          "| speed-up | max error |" + (" raised |" if norm == "Linf" else ""))
    print("|---:|---|---:|---:|---:|---:|---:|---:|---:|" + ("---:|" if norm == "Linf" else ""))
    for count in counts:
        for closure, rows in sorted(run(count, sets_of(count), rng, norm).items(), reverse=True):
            if not rows:
                continue
            ref, eps, ev, err, raised = np.array(rows, dtype=float).T
            ref_ms, eps_ms, ev_ms = (1e3 * float(np.nanmedian(x)) if not np.isnan(x).all() else np.nan
                                     for x in (ref, eps, ev))
            max_err = np.nan if np.isnan(err).all() else float(np.nanmax(err))
            line = (f"| {count} | {'closure' if closure else 'no closure'} | {len(rows)} "
                    f"| {cell(ref_ms)} | {cell(eps_ms)} | {cell(ref_ms / eps_ms, '.1f')}x "
                    f"| {cell(ev_ms)} | {cell(ref_ms / ev_ms, '.1f')}x | {cell(max_err, '.1e')} |")
            if norm == "L1":
                print(line)
            else:
                print(line.replace("| —x", "| —") + f" {int(raised.sum())} |")


def regression_cases() -> list[tuple[str, str, Callable[[], tuple]]]:
    """(case, call, thunk): issue 13's regression inputs and what each ran."""
    def linf(fn: Callable[..., object], case: tuple) -> Callable[[], object]:
        return lambda: fn(case[0], case[1], **case[2], norm="Linf")

    coplanar = coplanar_soft_case()
    cases = [("4 coplanar soft, 6 edges", name, linf(fn, coplanar))
             for name, fn in (("volume", volume), ("evaluate", evaluate), ("epsilon", epsilon))]
    cases.append(("4 coplanar soft, 6 edges", "truth (joggled_linf)",
                  lambda: joggled_truth(coplanar)))
    for n in (3, 4):
        cases.append((f"{n} soft on a sphere, 8 edges", "volume", linf(volume, soft_sphere_case(n))))
    cases.append(("3 soft on a sphere, 8 edges", "truth (joggled_linf)",
                  lambda: joggled_truth(soft_sphere_case(3))))
    return cases


def joggled_truth(case: tuple) -> object:
    """(epsilon, volume) by qhull 'QJ' of every Minkowski sum, if this
    version of reference.py has it (added with issue 13)."""
    joggled = getattr(reference_module, "joggled_linf", None)
    if joggled is None:
        raise LookupError("no joggled_linf in this version")
    eps, vol = joggled(*primitive_wrenches(case[0], case[1], **case[2]))
    return f"epsilon {eps:.6g}, volume {vol:.6g}"


def child(index: int, out: multiprocessing.connection.Connection) -> None:
    """Run regression case ``index`` under CHILD_MEMORY; send (outcome, s, peak MiB)."""
    resource.setrlimit(resource.RLIMIT_AS, (CHILD_MEMORY, CHILD_MEMORY))
    start = time.perf_counter()
    try:
        value = regression_cases()[index][2]()
        outcome = (f"epsilon {value.epsilon:.6g}, volume {value.volume:.6g}"
                   if hasattr(value, "volume") else value if isinstance(value, str) else f"{value:.6g}")
    except Exception as exc:                 # reported, not raised: the point of the table
        first = (str(exc).strip().splitlines() or [""])[0]
        outcome = f"{type(exc).__name__}: {first[:110]}"
    seconds = time.perf_counter() - start
    out.send((outcome, seconds, peak_rss_mib()))


def peak_rss_mib() -> float:
    """This process's peak resident memory [MiB] since its exec (VmHWM;
    ru_maxrss would also count the parent's RSS at fork time)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def print_regressions() -> None:
    ctx = multiprocessing.get_context("spawn")
    print(f"\n# issue 13 regression cases, each in a fresh process limited to "
          f"{CHILD_MEMORY / 2**30:.0f} GiB of address space")
    print("| case | call | result | seconds | peak RSS MiB |")
    print("|---|---|---|---:|---:|")
    for index, (case, call, _) in enumerate(regression_cases()):
        recv, send = ctx.Pipe(duplex=False)
        proc = ctx.Process(target=child, args=(index, send))
        proc.start()
        send.close()
        if recv.poll(CHILD_TIMEOUT):
            outcome, seconds, peak = recv.recv()
            row = f"{outcome} | {seconds:.2f} | {peak:.0f}"
        else:
            proc.kill()
            row = f"no answer within {CHILD_TIMEOUT:.0f} s (exit code {proc.exitcode}) | — | —"
        proc.join()
        print(f"| {case} | {call} | {row} |", flush=True)


def code_version() -> str:
    """Where the timed ``planner`` comes from, and its git commit."""
    where = Path(planner.__file__).resolve().parent.parent
    commit = subprocess.run(["git", "-C", str(where), "rev-parse", "--short", "HEAD"],
                            capture_output=True, text=True, check=False).stdout.strip()
    return f"{where} at {commit or 'unknown commit'}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sets", type=int, default=None,
                        help="sets per contact count and class (default 20 for L1, 5 for Linf)")
    parser.add_argument("--seed", type=int, default=20261122)
    parser.add_argument("--norm", choices=("L1", "Linf"), default="L1")
    opts = parser.parse_args()
    rng = np.random.default_rng(opts.seed)
    sets = opts.sets if opts.sets is not None else (20 if opts.norm == "L1" else 5)
    print(f"# {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"Python {platform.python_version()}, numpy {np.__version__}, scipy {scipy.__version__}, "
          f"load average {os.getloadavg()[0]:.2f}")
    if opts.norm == "L1":
        print(f"# sets per row <= {sets} (fewer for 16 contacts), seed {opts.seed}, "
              "median of per-set best-of-3 times")
        print_table(COUNTS, lambda count: sets if count < 16 else max(sets // 3, 3), rng, "L1")
        return
    print(f"# planner from {code_version()}")
    print(f"# norm Linf, sets per row <= {sets}, seed {opts.seed}, median of per-set "
          f"best-of-{LINF_REPEATS} times; 'raised' = calls that raised (not timed)")
    print(f"# skipped: reference above {LINF_REFERENCE_MAX} contacts (hull of 9^n Minkowski sums: "
          f"43 million points at 8); evaluate above {LINF_EVALUATE_MAX} contacts (Minkowski-sum "
          "vertices: ~18-54 s per call at 4 point contacts)")
    print_table(LINF_COUNTS, lambda count: sets, rng, "Linf")
    print_regressions()


if __name__ == "__main__":
    main()
