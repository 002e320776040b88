"""Barycentric coordinates of points on triangles: trimesh's ``points_to_barycentric`` (Cramer's rule) to the bit,
without its input checks and per-call set-up (a contact patch reads its closest points' features from them, once a
grasp)."""

from __future__ import annotations

import numpy as np

#: trimesh's ``diagonal_dot`` weights (a matrix-vector product that sums each row's products: the same BLAS call).
_ONES = np.ones(3)


def barycentric(triangles: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(n, 3) barycentric coordinates of ``points`` (n, 3) [m] on ``triangles`` (n, 3, 3) [m] (float64): the same
    products, sums and matrix-vector products as ``trimesh.triangles.points_to_barycentric(triangles, points)``,
    bit for bit (:func:`barycentric_reference`)."""
    edge = triangles[:, 1:] - triangles[:, :1]
    e0, e1 = edge[:, 0], edge[:, 1]
    w = points - triangles[:, 0]
    dot00, dot01, dot02 = np.dot(e0 * e0, _ONES), np.dot(e0 * e1, _ONES), np.dot(e0 * w, _ONES)
    dot11, dot12 = np.dot(e1 * e1, _ONES), np.dot(e1 * w, _ONES)
    inverse = 1.0 / (dot00 * dot11 - dot01 * dot01)
    out = np.empty((len(triangles), 3))
    out[:, 2] = (dot00 * dot12 - dot01 * dot02) * inverse
    out[:, 1] = (dot11 * dot02 - dot01 * dot12) * inverse
    out[:, 0] = 1 - out[:, 1] - out[:, 2]
    return out


def barycentric_reference(triangles: np.ndarray, points: np.ndarray) -> np.ndarray:
    """:func:`barycentric` by trimesh."""
    import trimesh

    return trimesh.triangles.points_to_barycentric(triangles, points)
