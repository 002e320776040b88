"""Benchmark: fast epsilon / evaluate against the plain qhull reference.

    python bench/quality.py [--sets N] [--seed S]

Contacts lie on a sphere of radius 5 cm (inward normals, random tangent roll),
uniform on a spherical cap around a random axis whose half-angle is uniform
in [45, 180] degrees (180 = the whole sphere), so that every contact count
gets both force-closure and non-closure sets.  Point contacts, 8 cone edges,
mu = 0.5, p = sphere centre, rho = 5 cm.  Each set is timed 3 times and the
best kept; the table shows the median over sets, all measured in this run.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import scipy

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from planner.quality import FORCE_CLOSURE_TOL, epsilon, evaluate, primitive_wrenches
from planner.quality.reference import reference_epsilon

RADIUS = 0.05
ARGS = {"mu": 0.5, "center": np.zeros(3), "torque_scale": RADIUS, "cone_edges": 8, "model": "point"}
COUNTS = (3, 4, 8, 16)
REPEATS = 3


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


def best_time(fn: Callable[..., object], *args: object) -> float:
    """Best of REPEATS wall-clock times of fn(*args, **ARGS) [s]."""
    best = np.inf
    for _ in range(REPEATS):
        start = time.perf_counter()
        fn(*args, **ARGS)
        best = min(best, time.perf_counter() - start)
    return best


def reference(points: np.ndarray, frames: np.ndarray, **args: object) -> float:
    """The plain path: all primitive wrenches, one default qhull."""
    return reference_epsilon(primitive_wrenches(points, frames, **args).wrenches)


def run(count: int, sets: int, rng: np.random.Generator) -> dict[bool, list[tuple]]:
    """Per class (closure or not): (reference, epsilon, evaluate) seconds and rel. error."""
    rows: dict[bool, list[tuple]] = {True: [], False: []}
    for _ in range(200 * sets):
        if min(len(v) for v in rows.values()) >= sets:
            break
        pts, frames = cap_grasp(rng, count)
        ref = reference(pts, frames, **ARGS)
        closure = ref > FORCE_CLOSURE_TOL
        if len(rows[closure]) >= sets:
            continue
        fast = epsilon(pts, frames, **ARGS)
        err = abs(fast - ref) / ref if closure else abs(fast - ref)
        rows[closure].append((best_time(reference, pts, frames), best_time(epsilon, pts, frames),
                              best_time(evaluate, pts, frames), err))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sets", type=int, default=20, help="sets per contact count and class")
    parser.add_argument("--seed", type=int, default=20261122)
    opts = parser.parse_args()
    rng = np.random.default_rng(opts.seed)
    print(f"# {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"Python {platform.python_version()}, numpy {np.__version__}, scipy {scipy.__version__}, "
          f"load average {os.getloadavg()[0]:.2f}")
    print(f"# sets per row <= {opts.sets} (fewer for 16 contacts), seed {opts.seed}, "
          "median of per-set best-of-3 times")
    print("| contacts | class | sets | reference ms | epsilon ms | speed-up | evaluate ms "
          "| speed-up | max error |")
    print("|---:|---|---:|---:|---:|---:|---:|---:|---:|")
    for count in COUNTS:
        sets = opts.sets if count < 16 else max(opts.sets // 3, 3)
        for closure, rows in sorted(run(count, sets, rng).items(), reverse=True):
            if not rows:
                continue
            ref, eps, ev, err = np.array(rows).T
            ref_ms, eps_ms, ev_ms = (1e3 * float(np.median(x)) for x in (ref, eps, ev))
            print(f"| {count} | {'closure' if closure else 'no closure'} | {len(rows)} "
                  f"| {ref_ms:.2f} | {eps_ms:.2f} | {ref_ms / eps_ms:.1f}x | {ev_ms:.2f} "
                  f"| {ref_ms / ev_ms:.1f}x | {err.max():.1e} |")


if __name__ == "__main__":
    main()
