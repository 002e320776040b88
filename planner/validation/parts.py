"""How an object collides in a shake trial.

Box, sphere and cylinder objects collide as PyBullet primitives (exact and
cheap). Every other object collides as its convex parts
(:mod:`planner.geometry.decompose`), each simplified to at most
``tolerance`` inside its hull: Bullet's GJK costs time linear in a hull's
vertices (the mug's 32 parts: 5,287 -> 632 vertices at 0.5 mm). CoACD parts of a
concave mesh are fatter than the mesh (the mug's by up to 3.0 mm, 1.75 mm at
the 95th percentile: ``bench/decomposition.py``); the trial records how deep
the open hand starts inside them.
"""

from __future__ import annotations

import io
import json

import numpy as np
import trimesh
from scipy.spatial import ConvexHull, QhullError

from planner import assets
from planner.geometry.decompose import convex_parts
from planner.geometry.solid import PreparedObject
from planner.sim.dynamics import Shape, part_file

PRIMITIVES = ("box", "sphere", "cylinder")
#: The most hull vertices a simplified part keeps.
MAX_VERTICES = 256

#: Bump when :func:`simplified_hull` changes what it returns (names the disk cache of simplified parts).
SIMPLIFY_VERSION = 1

_SHAPES: dict[tuple[str, float], Shape] = {}
_PARTS: dict[tuple[str, float], tuple[tuple[np.ndarray, np.ndarray], ...]] = {}


def trial_shape(obj: PreparedObject, tolerance: float) -> Shape:
    """The object's collision shape (memoised per process)."""
    if obj.spec.kind in PRIMITIVES:
        return Shape(obj.spec.kind, tuple(obj.spec.dims))
    key = (obj.mesh_hash, tolerance)
    if key not in _SHAPES:
        _SHAPES[key] = Shape("parts", files=tuple(part_file(v, f) for v, f in simplified_parts(obj, tolerance)))
    return _SHAPES[key]


def simplified_parts(obj: PreparedObject, tolerance: float) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
    """The object's convex parts, each as :func:`simplified_hull` (vertices
    (k, 3) [m], faces (f, 3)): what both trials collide. Memoised per process
    and cached on disk (simplifying a scan's parts costs seconds; CoACD's
    parts are cached the same way)."""
    key = (obj.mesh_hash, float(tolerance))
    if key in _PARTS:
        return _PARTS[key]
    name = assets.sha256_bytes(json.dumps([obj.mesh_hash, float(tolerance), MAX_VERTICES, SIMPLIFY_VERSION]).encode())
    path = assets.cache_dir("simplified") / f"{name[:24]}.npz"
    out = None
    if path.is_file():
        try:
            with np.load(path) as data:
                n = int(data["n"])
                out = tuple((data[f"v{i}"], data[f"f{i}"]) for i in range(n))
        except (OSError, ValueError, KeyError):
            path.unlink(missing_ok=True)
    if out is None:
        out = tuple(simplified_hull(v, tolerance) for v in convex_parts(obj.mesh, obj.mesh_hash).vertices)
        arrays = {f"{k}{i}": a for i, (v, f) in enumerate(out) for k, a in (("v", v), ("f", f))}
        buffer = io.BytesIO()
        np.savez(buffer, n=len(out), **arrays)
        assets.atomic_write(path, buffer.getvalue())
    _PARTS[key] = out
    return out


def simplified_hull(vertices: np.ndarray, tolerance: float) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (k, 3), faces (f, 3)) of a convex hull with fewer vertices,
    inside the hull of ``vertices`` (n, 3) [m] and within ``tolerance`` [m] of
    it: greedy refinement from 4 spread-out vertices, adding the hull vertex
    farthest outside the current hull until none is farther than
    ``tolerance`` (or MAX_VERTICES are kept). Deterministic."""
    try:
        v = np.asarray(vertices, float)[ConvexHull(vertices).vertices]
    except QhullError:  # a flat or degenerate part: keep it as it is
        return _hull(np.asarray(vertices, float))
    if tolerance <= 0 or len(v) <= 8:
        return _hull(v)
    chosen = _spread(v, 4)
    while len(chosen) < min(MAX_VERTICES, len(v)):
        try:
            planes = ConvexHull(v[chosen]).equations
        except QhullError:  # the first picks are coplanar: add the farthest from them
            chosen = _spread(v, len(chosen) + 1)
            continue
        outside = np.max(v @ planes[:, :3].T + planes[:, 3], axis=1)
        k = int(np.argmax(outside))
        if outside[k] <= tolerance:
            break
        chosen.append(k)
    return _hull(v[sorted(chosen)])


def _spread(v: np.ndarray, n: int) -> list[int]:
    """Indices of ``n`` vertices picked farthest-first from the one farthest from the mean."""
    chosen = [int(np.argmax(np.linalg.norm(v - v.mean(axis=0), axis=1)))]
    dist = np.linalg.norm(v - v[chosen[0]], axis=1)
    while len(chosen) < min(n, len(v)):
        k = int(np.argmax(dist))
        chosen.append(k)
        dist = np.minimum(dist, np.linalg.norm(v - v[k], axis=1))
    return chosen


def _hull(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    hull = trimesh.Trimesh(points).convex_hull
    return np.asarray(hull.vertices), np.asarray(hull.faces)
