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

The patches come from median splits of the triangle centroids along the
longest side of their bounding box, the largest patch split first, down to
at most ``faces`` triangles per patch or until there are ``most`` patches
(milliseconds for a mesh of thousands of triangles; no cache, no
decomposition run). The cap is PyBullet's: one body holds at most
:data:`planner.sim.MAX_LINKS` hulls, and a surface cut into more patches
than that lost the rest without a word (issue 26: a bottle of 2,160
triangles kept 127 of its 240 patches, so a finger met no hull where the
neck was and stepped through it; a capsule of 100k triangles kept 2%). A
finer mesh now gets larger patches of the same area.
"""

from __future__ import annotations

import heapq

import numpy as np
import trimesh

#: Triangles per patch: about 20-40 hull vertices, cheap to collide; the
#: hull of a small patch of a curved surface bulges out of it very little.
FACES_PER_PATCH = 16
#: At most this many patches: all of them fit in one PyBullet body (127 links).
MAX_PATCHES = 127


def surface_hulls(mesh: trimesh.Trimesh, faces: int = FACES_PER_PATCH, most: int = MAX_PATCHES
                  ) -> tuple[np.ndarray, ...]:
    """Vertex arrays ((k_i, 3) [m], object frame) of at most ``most``
    patches of ``mesh``'s surface, at most ``faces`` triangles each unless
    that would take more patches; every triangle is in exactly one patch."""
    if faces < 1 or most < 1:
        raise ValueError("surface_hulls: faces and most must be >= 1")
    centroids = np.asarray(mesh.triangles_center, float)
    # a heap of (-size, first triangle, triangles): the largest patch is split next
    heap = [(-len(centroids), 0, np.arange(len(centroids)))]
    while heap and -heap[0][0] > faces and len(heap) < most:
        _, _, index = heapq.heappop(heap)
        points = centroids[index]
        axis = int(np.argmax(np.ptp(points, axis=0)))
        order = index[np.argsort(points[:, axis], kind="stable")]
        half = len(order) // 2
        for part in (order[:half], order[half:]):
            heapq.heappush(heap, (-len(part), int(part.min()), part))
    leaves = [index for _, _, index in heap]
    triangles = np.asarray(mesh.faces)
    vertices = np.asarray(mesh.vertices, float)
    return tuple(vertices[np.unique(triangles[leaf])] for leaf in sorted(leaves, key=lambda leaf: int(leaf.min())))
