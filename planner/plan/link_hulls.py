"""The hands' links as convex hulls (PyBullet collides meshes as their hulls): their vertices and face planes,
link frame, for the grip measures (:mod:`planner.plan.grip`)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numpy as np
from scipy.spatial import ConvexHull

from planner.specs.hands import HandSpec
from planner.specs.urdf import load_model


@dataclass(frozen=True)
class Hull:
    """One link's convex collision hull, link frame.

    vertices : (v, 3) [m]; normals : (f, 3) outward unit face normals;
    offsets : (f,) [m], so that ``points @ normals.T - offsets`` is the
    signed distance of points to each face's plane (the largest of them:
    the signed distance to the hull inside it, a lower bound outside).
    """

    vertices: np.ndarray
    normals: np.ndarray
    offsets: np.ndarray

    @property
    def centre(self) -> np.ndarray:
        return self.vertices.mean(axis=0)

    @property
    def radius(self) -> float:
        return float(np.linalg.norm(self.vertices - self.centre, axis=1).max())


def hulls(hand: HandSpec) -> dict[str, Hull]:
    """Each contact link's convex collision hull (links with collision geometry)."""
    return _hulls(str(hand.urdf), hand.contact_links)


@cache
def _hulls(urdf: str, links: tuple[str, ...]) -> dict[str, Hull]:
    from planner.plan.patches import collision_mesh

    model = load_model(Path(urdf))
    out = {}
    for link in links:
        mesh = collision_mesh(model, link)
        if mesh is None:
            continue
        hull = ConvexHull(np.asarray(mesh.vertices, float))
        eq = planes(hull.equations)  # outward normals and offsets: n . x + c <= 0 inside
        out[link] = Hull(hull.points[hull.vertices], eq[:, :3].copy(), -eq[:, 3].copy())
    return out


def planes(equations: np.ndarray) -> np.ndarray:
    """Qhull's facet ``equations`` (f, 4) without exact repeats, in the order of their first occurrence.

    Qhull triangulates a flat face into triangles that carry the face's very
    plane (a meshed finger's hull: 252 triangles on 66 planes); a repeat
    changes no largest plane distance and no inside test, and a tie resolves
    to the first occurrence, which is kept.
    """
    order = np.lexsort(equations.T[::-1])  # stable: the first of equal rows leads them, as in np.unique
    ranked = equations[order]
    first = np.ones(len(ranked), bool)
    np.any(ranked[1:] != ranked[:-1], axis=1, out=first[1:])
    return equations[np.sort(order[first])]


def planes_reference(equations: np.ndarray) -> np.ndarray:
    """:func:`planes` by np.unique (its structured sort costs ~4x the lexsort on a hull's few dozen planes)."""
    _, first = np.unique(equations, axis=0, return_index=True)
    return equations[np.sort(first)]
