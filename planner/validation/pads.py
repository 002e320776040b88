"""Where a soft link touches: with its pad face, or with a sharp edge or
corner of its collision shape.

A pad's torsional friction (``torsion_radius`` of hand.toml) stands for the
contact patch its face makes on the object. A link whose planned contacts all
touch with its sharp edges or corners (a pad tilted against a face, a pad's
rim on a ball above its equator) has no such patch: Bullet would still give
each contact point the whole pad's spinning friction, so a trial switches it
off for that link (:func:`has_patch`).

Geometry: the convex hull of each collision element of the link (URDF,
link frame), as PyBullet collides them; planes as (k, 4) rows
``(unit outward normal, offset)`` with ``normal . x = offset`` on the face.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import cache
from pathlib import Path

import numpy as np
import trimesh

from planner.specs.urdf import load_model, mesh_path
from planner.validation.tolerances import PAD_ALIGN, PAD_EDGE, PAD_SHARP


@cache
def link_planes(urdf: Path, link: str) -> tuple[np.ndarray, ...]:
    """(k, 4) face planes of each collision element's convex hull, link frame;
    spheres and capsules (no sharp edges) give none (a hand's collision
    spheres are icospheres in its cut URDF: their many small faces meet at
    less than ``PAD_SHARP``, so no edge of theirs counts)."""
    out = []
    for element in load_model(urdf).link_map[link].collisions:
        g = element.geometry
        if g.mesh is not None:
            scale = 1.0 if g.mesh.scale is None else np.broadcast_to(np.asarray(g.mesh.scale, float), (3,))
            mesh = trimesh.load(mesh_path(urdf, g.mesh.filename), force="mesh")
            mesh.apply_scale(scale)
        elif g.box is not None:
            mesh = trimesh.creation.box(extents=g.box.size)
        elif g.cylinder is not None:
            mesh = trimesh.creation.cylinder(radius=g.cylinder.radius, height=g.cylinder.length, sections=32)
        else:
            continue
        hull = mesh.convex_hull
        hull.apply_transform(np.eye(4) if element.origin is None else element.origin)
        normals = hull.face_normals
        out.append(np.column_stack([normals, np.einsum("ij,ij->i", normals, hull.triangles[:, 0])]))
    return tuple(out)


def on_edge(planes: Sequence[np.ndarray], point: np.ndarray, normal: np.ndarray) -> bool:
    """Whether a contact at ``point`` (3,) [m] with the object's inward
    ``normal`` (3,) there (link frame) touches an edge or corner of the link:
    the point lies within PAD_EDGE of an edge where faces meet at more than
    PAD_SHARP (on the element it is nearest to), and the object's surface is
    not parallel (within PAD_ALIGN) to one of the faces there (a face lying
    flat on the pad up to its rim is a patch)."""
    if not planes:
        return False
    heights = [p[:, :3] @ point - p[:, 3] for p in planes]
    best = int(np.argmax([h.max() for h in heights]))
    near = planes[best][heights[best] > heights[best].max() - PAD_EDGE, :3]
    sharp = (near @ near.T).min() < np.cos(PAD_SHARP)
    return bool(sharp and (near @ normal).max() < np.cos(PAD_ALIGN))


def has_patch(planes: Sequence[np.ndarray], points: np.ndarray, normals: np.ndarray) -> bool:
    """Whether a soft link touching at ``points`` (n, 3) with the object's
    inward ``normals`` (n, 3) there (link frame) does so with a contact patch
    of its face: not all of them on its edges or corners (:func:`on_edge`)."""
    return not all(on_edge(planes, p, n) for p, n in zip(points, normals))
