"""A surface's normal at the scale of a contact, not of one triangle.

A scan's triangles carry its noise: 0.1 mm of noise on triangles 0.5 mm
across tilts their normals by 10-20 degrees, and a decimation of it (a
collision proxy, :mod:`planner.geometry.proxy`) has facets tilted by as
much at a larger scale. A finger pad pressed on such a surface meets it over
millimetres, not over one triangle, so the contact's normal is the
surface's mean over that scale: the area-weighted mean of the outward
normals of the faces whose centres lie within ``radius`` of the point (those
facing the same side: a thin wall's far side is not averaged in).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import trimesh
from scipy.spatial import cKDTree

#: Faces whose normal is farther than this [rad] from the point's own face's
#: (then from the first mean) are left out: a wall's far side, an edge's
#: other face; a scan's noise tilts its triangles by less.
SAME_SIDE = np.radians(60.0)

#: Points whose discs :meth:`ScaleNormals.at` gathers at once: a point's normal
#: does not depend on the others', and one gather of a large scan's 200,000
#: grip samples (a 1M-face capsule of 0.3 m^2, ~80 faces a disc) took 2 GB more
#: than the faces' own normals and 14 s; in blocks: ~60 MB more and 9 s.
BLOCK = 8192


@dataclass
class ScaleNormals:
    """Normals of ``mesh`` (object frame [m]) averaged over a disc."""

    mesh: trimesh.Trimesh

    @cached_property
    def _centres(self) -> cKDTree:
        return cKDTree(self.mesh.triangles_center)

    def at(self, points: np.ndarray, face: np.ndarray, radius: float,
           toward: np.ndarray | None = None) -> np.ndarray:
        """(n, 3) outward unit normals at ``points`` (n, 3) on faces ``face``
        (n,): the area-weighted mean of the normals of the faces centred
        within ``radius`` [m] (the point's own face always in), twice: first
        of those within ``SAME_SIDE`` of ``toward`` (n, 3), the outward
        normals the points are known to have at a coarser scale (a contact's
        on a collision proxy, its sharp edges' normal cones included), else
        of the point's own face's normal (a box's other face at an edge is
        left out: the mean is the face's own normal), then of those within
        ``SAME_SIDE`` of that first mean. Where nothing is kept: ``toward``,
        else the own face's normal. (A point on an edge lies on both its
        faces, and which one a closest-point query names is a tie: a
        contact on a box's edge, its proxy's normal the diagonal between the
        faces, took one face's normal or the other's, 45 degrees off.)"""
        points = np.asarray(points, float).reshape(-1, 3)
        face = np.asarray(face, np.int64).reshape(-1)
        if len(points) > BLOCK:  # the same normals to the bit, the memory of one block
            toward = None if toward is None else np.asarray(toward, float).reshape(-1, 3)
            return np.vstack([self.at(points[i:i + BLOCK], face[i:i + BLOCK], radius,
                                      None if toward is None else toward[i:i + BLOCK])
                              for i in range(0, len(points), BLOCK)])
        normals, area = self.mesh.face_normals, self.mesh.area_faces
        seed = normals[face] if toward is None else toward
        mean = np.array(seed, float).reshape(-1, 3)
        count = len(points)
        if count == 0:
            return mean
        near = self._centres.query_ball_point(points, radius)
        sizes = np.fromiter(map(len, near), np.int64, count)
        owner = np.repeat(np.arange(count), sizes)  # each point's faces, then its own face where not among them
        faces = np.fromiter(itertools.chain.from_iterable(near), np.int64, int(sizes.sum()))
        among = np.zeros(count, bool)
        among[owner[faces == face[owner]]] = True
        owner, faces = np.r_[owner, np.flatnonzero(~among)], np.r_[faces, face[~among]]
        n, w = normals[faces], area[faces]
        going = np.ones(count, bool)  # a point whose pass keeps nothing stops at its last mean
        for _ in range(2):
            keep = going[owner] & (np.einsum("ij,ij->i", n, mean[owner]) > np.cos(SAME_SIDE))
            total = np.column_stack([np.bincount(owner[keep], n[keep, k] * w[keep], count) for k in range(3)])
            length = np.linalg.norm(total, axis=1)
            going &= length > 0
            mean[going] = total[going] / length[going, None]
        return mean
