"""Exact closest points on a mesh (libigl's AABB tree): known answers on a
unit cube, every face tried on a random mesh, survives pickling, bad input a
MeshError."""

import pickle

import numpy as np
import pytest
import trimesh
from helpers import NUM_TOL, brute_distances
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.errors import MeshError
from planner.geometry.distance import MeshDistance


def cube() -> MeshDistance:
    box = trimesh.creation.box((1.0, 1.0, 1.0))
    return MeshDistance(box.vertices, box.faces)


def test_known_distances_to_a_unit_cube() -> None:
    points = np.array([[0.0, 0.0, 2.0], [0.0, 0.0, 0.25], [1.5, 1.5, 0.0], [1.0, 1.0, 1.0], [0.5, 0.0, 0.0]])
    found = cube().nearest(points)
    assert np.allclose(found.distance, [1.5, 0.25, np.sqrt(2.0), np.sqrt(3.0) / 2, 0.0], atol=NUM_TOL)
    assert np.allclose(found.points, [[0, 0, 0.5], [0, 0, 0.5], [0.5, 0.5, 0], [0.5, 0.5, 0.5], [0.5, 0, 0]],
                       atol=NUM_TOL)


def test_no_points_no_answers() -> None:
    found = cube().nearest(np.zeros((0, 3)))
    assert found.points.shape == (0, 3) and found.distance.shape == (0,) and found.face.shape == (0,)


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_the_nearest_of_every_face(seed: int) -> None:
    rng = np.random.default_rng(seed)
    mesh = trimesh.creation.icosphere(1, 0.05)
    mesh.vertices += rng.normal(scale=0.01, size=mesh.vertices.shape)  # a lumpy, non-convex solid
    points = rng.normal(scale=0.06, size=(60, 3))
    found = MeshDistance(mesh.vertices, mesh.faces).nearest(points)
    assert np.allclose(found.distance, brute_distances(mesh.triangles, points), atol=NUM_TOL)
    on_face = [brute_distances(mesh.triangles[f][None], c[None])[0] for f, c in zip(found.face, found.points)]
    assert np.allclose(on_face, 0.0, atol=NUM_TOL)


def test_a_pickled_tree_answers_the_same() -> None:
    tree = cube()
    points = np.random.default_rng(0).normal(size=(20, 3))
    again = pickle.loads(pickle.dumps(tree))
    for a, b in zip(vars(tree.nearest(points)).values(), vars(again.nearest(points)).values()):
        assert np.array_equal(a, b)


@pytest.mark.parametrize("vertices, faces", [(np.zeros((3, 2)), np.array([[0, 1, 2]])),
                                             (np.zeros((3, 3)), np.zeros((0, 3), int)),
                                             (np.zeros((3, 3)), np.array([[0, 1, 3]]))])
def test_bad_meshes_are_refused(vertices: np.ndarray, faces: np.ndarray) -> None:
    with pytest.raises(MeshError):
        MeshDistance(vertices, faces)
