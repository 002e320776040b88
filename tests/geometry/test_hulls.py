"""Surface hulls: every triangle in one patch; the hulls bound the distance
to the surface from below."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.spatial import ConvexHull, Delaunay

from planner.geometry.hulls import MAX_PATCHES, surface_hulls
from planner.geometry.solid import load_object

#: Two triangulations of the same surface give closest points this far apart [m].
NUMERIC_TOL = 1e-7


@pytest.mark.parametrize("faces", [1, 4, 16, 64])
def test_every_vertex_of_every_triangle_is_in_a_patch_hull(faces: int) -> None:
    mesh = load_object("mug").mesh
    patches = surface_hulls(mesh, faces, most=len(mesh.faces))
    assert len(patches) >= len(mesh.faces) / faces
    covered = set()
    for vertices in patches:
        rows = {tuple(v) for v in np.round(vertices, 12)}
        covered |= rows
    assert covered == {tuple(v) for v in np.round(mesh.vertices[np.unique(mesh.faces)], 12)}


def test_distance_to_the_hulls_never_exceeds_the_distance_to_the_surface() -> None:
    mesh = trimesh.creation.icosphere(subdivisions=2, radius=0.05)
    patches = surface_hulls(mesh, 8)
    rng = np.random.default_rng(0)
    probes = rng.uniform(-0.1, 0.1, (300, 3))
    exact = np.abs(trimesh.proximity.signed_distance(mesh, probes))
    lower = np.min([_hull_distances(v, probes) for v in patches], axis=0)
    assert np.all(lower <= exact + NUMERIC_TOL)
    assert np.mean(lower > 0.5 * exact) > 0.5  # a bound, not a trivial one


def _hull_distances(vertices: np.ndarray, probes: np.ndarray) -> np.ndarray:
    """Distances from ``probes`` (n, 3) to the convex hull of ``vertices`` (0 inside)."""
    hull = ConvexHull(vertices)
    inside = Delaunay(vertices).find_simplex(probes) >= 0
    _, distance, _ = trimesh.proximity.closest_point(trimesh.Trimesh(vertices, hull.simplices, process=False), probes)
    return np.where(inside, 0.0, distance)


def test_a_fine_mesh_gets_at_most_most_patches_covering_every_triangle() -> None:
    # 8,192 triangles: 512 patches of 16, more than one PyBullet body holds (issue 26)
    mesh = trimesh.creation.capsule(height=0.07, radius=0.022, count=[64, 64])
    patches = surface_hulls(mesh)
    assert len(patches) == MAX_PATCHES
    sizes = [len(p) for p in patches]
    assert max(sizes) <= 2 * min(sizes) + 8  # the largest is split first: patches of about one size
    covered = {tuple(v) for p in patches for v in np.round(p, 12)}
    assert covered == {tuple(v) for v in np.round(mesh.vertices[np.unique(mesh.faces)], 12)}


def test_bad_patch_size_is_refused() -> None:
    with pytest.raises(ValueError):
        surface_hulls(load_object("box").mesh, 0)
    with pytest.raises(ValueError):
        surface_hulls(load_object("box").mesh, 16, 0)
