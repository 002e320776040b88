"""Approach sampling: where and from which direction the hand comes in.

Two samplers, both OpenRAVE-style rays onto the surface:

- ``surface``: area-weighted random surface points with their outward
  normals (needs the seeded generator);
- ``box``: the bounding box grown by 1 cm, each face gridded every ``delta``
  metres, rays cast inward; each first hit gives a point and its normal.

An optional *fan* adds directions tilted by ``fan_angle`` around each normal.
The hand approaches along ``direction`` (into the object); the approach ray
passes through ``point``. All vectors in the object frame, lengths in metres.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
import trimesh

from planner.errors import InputError
from planner.geometry.frames import tilted
from planner.plan.tolerances import BOX_MARGIN

SAMPLERS = ("surface", "box")


@dataclass(frozen=True)
class Approaches:
    """A batch of approach rays.

    Attributes:
        points: (n, 3) surface points [m], object frame.
        normals: (n, 3) unit outward surface normals at ``points``.
        directions: (n, 3) unit approach directions (into the object).
    """

    points: np.ndarray
    normals: np.ndarray
    directions: np.ndarray

    def __post_init__(self) -> None:
        n = len(self.points)
        for name in ("points", "normals", "directions"):
            if getattr(self, name).shape != (n, 3):
                raise ValueError(f"Approaches.{name} must be (n, 3)")

    def __len__(self) -> int:
        return len(self.points)


def sample(mesh: trimesh.Trimesh, *, sampler: str, count: int, rng: np.random.Generator,
           delta: float = 0.02, fan_count: int = 0, fan_angle: float = 0.3) -> Approaches:
    """Sample approach rays on ``mesh`` (see module docstring)."""
    if sampler == "surface":
        if count < 1:
            raise InputError(f"--approaches must be at least 1, got {count}")
        points, faces = trimesh.sample.sample_surface(mesh, count, seed=rng)
        normals = mesh.face_normals[faces]
    elif sampler == "box":
        points, normals = _box_rays(mesh, delta)
    else:
        raise InputError(f"unknown sampler '{sampler}'; use {', '.join(SAMPLERS)}")
    base = Approaches(np.asarray(points, float), np.asarray(normals, float), -np.asarray(normals, float))
    return fan(base, fan_count, fan_angle) if fan_count > 0 else base


def _box_rays(mesh: trimesh.Trimesh, delta: float) -> tuple[np.ndarray, np.ndarray]:
    if delta <= 0:
        raise InputError(f"box sampler spacing must be positive, got {delta}")
    lo, hi = mesh.bounds[0] - BOX_MARGIN, mesh.bounds[1] + BOX_MARGIN
    origins, dirs = [], []
    for axis in range(3):
        u, v = [a for a in range(3) if a != axis]
        us = np.arange(lo[u], hi[u] + 1e-12, delta)
        vs = np.arange(lo[v], hi[v] + 1e-12, delta)
        grid = np.array(list(itertools.product(us, vs)))
        for side, start in ((1.0, lo[axis]), (-1.0, hi[axis])):
            o = np.zeros((len(grid), 3))
            o[:, u], o[:, v], o[:, axis] = grid[:, 0], grid[:, 1], start
            d = np.zeros_like(o)
            d[:, axis] = side
            origins.append(o)
            dirs.append(d)
    o, d = np.vstack(origins), np.vstack(dirs)
    hits, rays, tris = mesh.ray.intersects_location(o, d, multiple_hits=False)
    order = np.argsort(rays, kind="stable")
    return hits[order], mesh.face_normals[tris[order]]


def fan(base: Approaches, count: int, angle: float) -> Approaches:
    """Add ``count`` directions tilted by ``angle`` [rad] around each normal."""
    points, normals, dirs = [base.points], [base.normals], [base.directions]
    for k in range(count):
        phi = 2 * np.pi * k / count
        points.append(base.points)
        normals.append(base.normals)
        dirs.append(tilted(base.directions, angle, phi))
    return Approaches(np.vstack(points), np.vstack(normals), np.vstack(dirs))
