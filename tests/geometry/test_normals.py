"""A surface's normal at a contact's scale (planner.geometry.normals)."""

from __future__ import annotations

import numpy as np
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from planner.geometry.normals import ScaleNormals


def _rough_plane(noise: float, seed: int = 0) -> trimesh.Trimesh:
    """A 2 cm square in z = 0 of ~0.5 mm triangles, its vertices moved along z by noise [m]."""
    n = 41
    x, y = np.meshgrid(np.linspace(-0.01, 0.01, n), np.linspace(-0.01, 0.01, n))
    z = np.random.default_rng(seed).normal(0.0, noise, x.shape)
    index = np.arange(n * n).reshape(n, n)
    a, b, c, d = index[:-1, :-1].ravel(), index[:-1, 1:].ravel(), index[1:, :-1].ravel(), index[1:, 1:].ravel()
    faces = np.vstack([np.column_stack([a, b, d]), np.column_stack([a, d, c])])
    return trimesh.Trimesh(np.column_stack([x.ravel(), y.ravel(), z.ravel()]), faces, process=False)


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", a, b), -1.0, 1.0)))


def test_a_rough_surfaces_normal_at_a_contacts_scale_is_its_shapes() -> None:
    """0.1 mm of noise tilts single triangles by up to tens of degrees; over a 2 mm disc the mean is within a few
    degrees of the plane's normal."""
    mesh = _rough_plane(1e-4)
    face = np.arange(0, len(mesh.faces), 97)
    face = face[np.abs(mesh.triangles_center[face, :2]).max(axis=1) < 0.007]  # the disc inside the square
    up = np.tile([0.0, 0.0, 1.0], (len(face), 1))
    assert _angle(mesh.face_normals[face], up).max() > 15.0  # one triangle's
    assert _angle(ScaleNormals(mesh).at(mesh.triangles_center[face], face, 0.002), up).max() < 4.0


def test_near_a_sharp_edge_a_face_keeps_its_own_normal() -> None:
    """A box's other face within the radius is not averaged in: a point 1 mm from an edge has its face's normal."""
    box = trimesh.creation.box(extents=(0.04, 0.04, 0.04)).subdivide_to_size(0.001)
    points = np.array([[0.019, 0.0, 0.02], [0.0, -0.019, 0.02], [0.02, 0.005, -0.019]])
    _, _, face = trimesh.proximity.closest_point(box, points)
    near = ScaleNormals(box)._centres.query_ball_point(points, 0.002)
    assert all((box.face_normals[n] @ box.face_normals[f] < 0.5).any() for n, f in zip(near, face))  # the other face's
    got = ScaleNormals(box).at(points, face, 0.002)
    assert np.allclose(got, box.face_normals[face], atol=1e-12)


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**31 - 1), st.floats(0.0005, 0.003))
def test_the_normals_turn_with_the_surface(seed: int, radius: float) -> None:
    """Rotating the mesh and its points rotates their normals (the disc is a ball: no frame is preferred)."""
    mesh = trimesh.creation.icosphere(4, 0.02)
    rng = np.random.default_rng(seed)
    mesh.vertices += mesh.vertex_normals * rng.normal(0.0, 1e-4, (len(mesh.vertices), 1))
    face = rng.choice(len(mesh.faces), 8, replace=False)
    points = mesh.triangles_center[face]
    turn = Rotation.random(random_state=seed).as_matrix()
    turned = trimesh.Trimesh(mesh.vertices @ turn.T, mesh.faces, process=False)
    expected = ScaleNormals(mesh).at(points, face, radius) @ turn.T
    assert np.allclose(ScaleNormals(turned).at(points @ turn.T, face, radius), expected, atol=1e-9)


def test_on_a_sharp_edge_the_normal_is_on_the_known_side() -> None:
    """A point on a box's edge lies on both its faces; given the normal it has at a coarser scale (a proxy's
    contact: the diagonal of the edge's cone), it is the mean of both faces', not the face a closest-point query
    happened to name."""
    box = trimesh.creation.box(extents=(0.04, 0.04, 0.04)).subdivide_to_size(0.001)
    points = np.array([[0.02, 0.02, 0.0], [0.02, 0.02, 0.005]])
    _, _, face = trimesh.proximity.closest_point(box, points)
    diagonal = np.tile([np.sqrt(0.5), np.sqrt(0.5), 0.0], (2, 1))
    got = ScaleNormals(box).at(points, face, 0.002, toward=diagonal)
    assert _angle(got, diagonal).max() < 10.0
    assert np.allclose(ScaleNormals(box).at(points, face, 0.002), box.face_normals[face])  # the face's own
    flat = ScaleNormals(box).at(points - [0.001, 0.0, 0.0], face, 0.002, toward=np.tile([0.0, 1.0, 0.0], (2, 1)))
    assert np.allclose(flat, [0.0, 1.0, 0.0], atol=1e-12)  # a pad lying on the face 1 mm from the edge


def _reference(mesh: trimesh.Trimesh, points: np.ndarray, face: np.ndarray, radius: float,
               toward: np.ndarray | None) -> np.ndarray:
    """ScaleNormals.at written point by point."""
    from planner.geometry.normals import SAME_SIDE

    tree = cKDTree(mesh.triangles_center)
    out = np.array(mesh.face_normals[face] if toward is None else toward, float)
    for i, near in enumerate(tree.query_ball_point(points, radius)):
        near = np.union1d(np.asarray(near, np.int64), [face[i]])
        n, w = mesh.face_normals[near], mesh.area_faces[near]
        mean = out[i]
        for _ in range(2):
            keep = n @ mean > np.cos(SAME_SIDE)
            total = (n[keep] * w[keep, None]).sum(axis=0)
            if np.linalg.norm(total) <= 0:
                break
            mean = total / np.linalg.norm(total)
        out[i] = mean
    return out


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**31 - 1), st.floats(0.0005, 0.004), st.booleans())
def test_the_normals_at_once_are_the_normals_point_by_point(seed: int, radius: float, steer: bool) -> None:
    rng = np.random.default_rng(seed)
    mesh = trimesh.creation.box(extents=(0.03, 0.02, 0.01)).subdivide().subdivide().subdivide()
    mesh.vertices += rng.normal(0.0, 2e-4, mesh.vertices.shape)
    face = rng.choice(len(mesh.faces), 30)
    points = mesh.triangles_center[face] + rng.normal(0.0, 1e-4, (30, 3))
    toward = None
    if steer:
        toward = mesh.face_normals[face] + rng.normal(0.0, 0.5, (30, 3))
        toward /= np.linalg.norm(toward, axis=1, keepdims=True)
    assert np.allclose(ScaleNormals(mesh).at(points, face, radius, toward),
                       _reference(mesh, points, face, radius, toward), atol=1e-12)


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**31 - 1), st.floats(0.0002, 0.004), st.booleans())
def test_a_point_whose_own_face_is_centred_beyond_the_radius_keeps_it(seed: int, radius: float, steer: bool) -> None:
    """The test above puts each point within 0.2 mm of its face's centre, always within the radius: the point's
    own face added where the ball query misses it (large faces, a small radius) was never run there (dropping it
    passed every test). Points anywhere on faces of mixed sizes, some of them alone in their ball."""
    rng = np.random.default_rng(seed)
    mesh = trimesh.creation.box(extents=(0.03, 0.02, 0.01))
    mesh = mesh.subdivide(face_index=rng.choice(12, 6, replace=False)).subdivide(face_index=np.arange(4))
    mesh.vertices += rng.normal(0.0, 2e-4, mesh.vertices.shape)
    points, face = trimesh.sample.sample_surface(mesh, 40, seed=rng)
    points = points + rng.normal(0.0, 1e-4, points.shape)
    toward = None
    if steer:
        toward = mesh.face_normals[face] + rng.normal(0.0, 0.5, (40, 3))
        toward /= np.linalg.norm(toward, axis=1, keepdims=True)
    near = cKDTree(mesh.triangles_center).query_ball_point(points, radius)
    assert any(f not in n for f, n in zip(face, near))  # the case this test is for
    assert np.allclose(ScaleNormals(mesh).at(points, face, radius, toward),
                       _reference(mesh, points, face, radius, toward), atol=1e-12)


def test_many_points_are_gathered_a_block_at_a_time_to_the_same_normals(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """The grip measures' 200,000 samples of a large scan gathered at once held every face of every sample's disc
    at once (2 GB more on a 1M-face capsule): at most ``BLOCK`` points' discs are gathered at a time, and the
    normals are those of one gather, to the bit, with ``toward`` and without."""
    from planner.geometry import normals

    rng = np.random.default_rng(3)
    mesh = _rough_plane(1e-4)
    points, face = trimesh.sample.sample_surface(mesh, 1000, seed=rng)
    toward = mesh.face_normals[face] + rng.normal(0.0, 0.3, (1000, 3))
    whole = ScaleNormals(mesh)
    expected = [whole.at(points, face, 0.002), whole.at(points, face, 0.002, toward)]
    monkeypatch.setattr(normals, "BLOCK", 64, raising=False)
    blocked = ScaleNormals(mesh)
    sizes: list[int] = []
    tree = blocked._centres

    class Counted:
        def query_ball_point(self, x, r):  # type: ignore[no-untyped-def]
            sizes.append(len(x))
            return tree.query_ball_point(x, r)

    blocked.__dict__["_centres"] = Counted()
    assert np.array_equal(blocked.at(points, face, 0.002), expected[0])
    assert np.array_equal(blocked.at(points, face, 0.002, toward), expected[1])
    assert max(sizes) <= 64 and sum(sizes) == 2000, (max(sizes), sum(sizes))
