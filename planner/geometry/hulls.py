"""A coarse stand-in for the surface of a mesh: small patches of its
triangles, each to be collided as the convex hull of its vertices (not to be
confused with the contact patches of contact reading, which describe
where a finger touches).

Why (closing's far field, :mod:`planner.plan.closing`): PyBullet's distance
query against the exact concave mesh costs ~4-5 us per *triangle* within
range, and closing asks with ranges of a centimetre or more. Against the
patches it costs one convex-convex query per *patch* within range. The
hulls contain the surface (each triangle lies in its patch's hull), so the
distance to a hull is a lower bound of the distance to that part of the
surface and a link may safely advance by it; only once a link comes close
does closing ask the exact mesh, with a short range.

The patches come from a median split of the triangle centroids along the
longest side of their bounding box, down to at most ``faces`` triangles per
patch (milliseconds for a mesh of thousands of triangles; no cache, no
decomposition run).
"""

from __future__ import annotations

import numpy as np
import trimesh

#: Triangles per patch: about 20-40 hull vertices, cheap to collide; the
#: hull of a small patch of a curved surface bulges out of it very little.
FACES_PER_PATCH = 16


def surface_hulls(mesh: trimesh.Trimesh, faces: int = FACES_PER_PATCH) -> tuple[np.ndarray, ...]:
    """Vertex arrays ((k_i, 3) [m], object frame) of the patches of
    ``mesh``'s surface, at most ``faces`` triangles each; every triangle is
    in exactly one patch."""
    if faces < 1:
        raise ValueError("surface_hulls: faces must be >= 1")
    centroids = np.asarray(mesh.triangles_center, float)
    leaves: list[np.ndarray] = []
    todo = [np.arange(len(centroids))]
    while todo:
        index = todo.pop()
        if len(index) <= faces:
            leaves.append(index)
            continue
        points = centroids[index]
        axis = int(np.argmax(np.ptp(points, axis=0)))
        order = index[np.argsort(points[:, axis], kind="stable")]
        half = len(order) // 2
        todo += [order[half:], order[:half]]
    triangles = np.asarray(mesh.faces)
    vertices = np.asarray(mesh.vertices, float)
    return tuple(vertices[np.unique(triangles[leaf])] for leaf in sorted(leaves, key=lambda leaf: int(leaf.min())))
