"""Exact closest points on a mesh (libigl's AABB tree): known answers on a
unit cube, every face tried on a random mesh, survives pickling, bad input a
MeshError. The signed distance: known signs at a cube's faces, edges and
corners, the inside of a lumpy solid and of a hollow one (a mug-like cup)
agree with an independent inside test (trimesh's ray casting); where two
bodies overlap the winding number gives the side the pseudonormals miss
(points inside one body, nearest to a face of the other buried in it), and
only there: one closed body, or bodies far apart, use the pseudonormals
alone, an open mesh the winding number everywhere. The grid of
distance bounds: every point's exact distance lies between its bounds, in
and off the grid, whatever was asked before; exact at the nodes; no more
nodes than allowed."""

import pickle

import numpy as np
import pytest
import trimesh
from helpers import NUM_TOL, brute_distances
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.errors import MeshError
from planner.geometry.distance import DistanceBounds, MeshDistance


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


def test_signs_at_a_cubes_faces_edges_and_corners() -> None:
    # points whose closest feature is a face, an edge or a corner, inside and out: the face normal alone
    # gives the wrong side near a convex edge, the pseudonormal never does
    points = np.array([[0.0, 0.0, 0.7], [0.6, 0.6, 0.0], [0.6, 0.6, 0.6], [0.0, 0.0, 0.3], [0.45, 0.45, 0.0],
                       [0.45, 0.45, 0.45], [0.6, 0.55, 0.0], [0.55, 0.9, 0.0]])
    signed = cube().signed(points)
    expected = [0.2, np.sqrt(0.02), np.sqrt(0.03), -0.2, -0.05, -0.05, np.hypot(0.1, 0.05), np.hypot(0.05, 0.4)]
    assert np.allclose(signed, expected, atol=NUM_TOL)
    assert cube().signed(np.zeros((0, 3))).shape == (0,)


def _cup() -> trimesh.Trimesh:
    """A closed cup: a cylinder with a smaller one taken out of its top (walls 1 cm, floor 1 cm)."""
    outer = trimesh.creation.cylinder(0.04, 0.1, sections=24)
    inner = trimesh.creation.cylinder(0.03, 0.1, sections=24)
    inner.apply_translation([0.0, 0.0, 0.01 + 0.001])
    return outer.difference(inner, engine="manifold")


@settings(max_examples=10, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from(["lumpy", "cup"]))
def test_the_sign_agrees_with_an_independent_inside_test(seed: int, kind: str) -> None:
    rng = np.random.default_rng(seed)
    if kind == "lumpy":
        mesh = trimesh.creation.icosphere(2, 0.05)
        mesh.vertices += rng.normal(scale=0.002, size=mesh.vertices.shape)  # lumps, no folds
    else:
        mesh = _cup()
    lo, hi = mesh.bounds
    points = rng.uniform(lo - 0.01, hi + 0.01, size=(300, 3))
    distance = MeshDistance(mesh.vertices, mesh.faces)
    signed = distance.signed(points)
    assert np.allclose(np.abs(signed), distance.nearest(points).distance)
    clear = np.abs(signed) > 1e-6  # ray casting is unreliable on the surface itself
    assert np.array_equal((signed < 0)[clear], mesh.contains(points)[clear])


def _two_overlapping_cubes() -> trimesh.Trimesh:
    """Two unit cubes, the second shifted by half a side along x: one mesh of two closed bodies whose
    faces at x = 0 and x = 0.5 each lie inside the other body."""
    a = trimesh.creation.box((1.0, 1.0, 1.0))
    b = a.copy()
    b.apply_translation([0.5, 0.0, 0.0])
    return trimesh.util.concatenate([a, b])


@settings(max_examples=10, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_the_winding_number_sides_points_where_bodies_overlap(seed: int) -> None:
    mesh = _two_overlapping_cubes()
    distance = MeshDistance(mesh.vertices, mesh.faces)
    rng = np.random.default_rng(seed)
    points = rng.uniform([-0.8, -0.8, -0.8], [1.3, 0.8, 0.8], size=(400, 3))
    inside_a = np.all(np.abs(points) < 0.5, axis=1)
    inside_b = np.all(np.abs(points - [0.5, 0.0, 0.0]) < 0.5, axis=1)
    winding = distance.winding(points)
    assert np.allclose(winding, inside_a.astype(float) + inside_b, atol=0.01)  # the sum over bodies
    signed = distance.signed(points)
    assert np.allclose(np.abs(signed), distance.nearest(points).distance)
    assert np.array_equal(signed < 0, inside_a | inside_b)
    # inside one cube, nearest to the other's face buried in it: the pseudonormals alone read them outside
    buried = np.array([[-0.05, 0.0, 0.0], [0.55, 0.3, -0.2]])
    assert (distance.signed(buried) < 0).all()
    assert distance.winding(np.zeros((0, 3))).shape == (0,)


def test_the_winding_number_only_where_the_pseudonormals_can_fail() -> None:
    assert not cube()._unsure.any()
    apart = trimesh.creation.box((1.0, 1.0, 1.0))
    other = apart.copy()
    other.apply_translation([3.0, 0.0, 0.0])
    assert not MeshDistance(*_arrays(trimesh.util.concatenate([apart, other])))._unsure.any()
    two = _two_overlapping_cubes()
    x = two.triangles[:, :, 0]
    far_ends = np.isclose(x, -0.5).all(axis=1) | np.isclose(x, 1.0).all(axis=1)
    # the outer ends (x = -0.5 and x = 1) are off the other cube's box; every other face meets it
    assert np.array_equal(MeshDistance(*_arrays(two))._unsure, ~far_ends) and far_ends.sum() == 4
    open_box = trimesh.creation.box((1.0, 1.0, 1.0))
    open_box.update_faces(np.arange(len(open_box.faces)) != 0)  # one triangle taken out: an open mesh
    assert MeshDistance(*_arrays(open_box))._unsure.all()


def _arrays(mesh: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray]:
    return np.asarray(mesh.vertices), np.asarray(mesh.faces)


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


def lumpy(seed: int) -> trimesh.Trimesh:
    rng = np.random.default_rng(seed)
    mesh = trimesh.creation.icosphere(2, 0.05)
    mesh.vertices += rng.normal(scale=0.008, size=mesh.vertices.shape)
    return mesh


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(0.001, 0.02))
def test_the_exact_distance_lies_between_the_grids_bounds(seed: int, spacing: float) -> None:
    """Points near the surface, inside it and far off the grid (clamped to its
    border), asked in two orders on two grids: the same bounds, around the
    exact distance, and the gap between them at most a node's diagonal
    inside the grid."""
    mesh = lumpy(seed)
    tree = MeshDistance(mesh.vertices, mesh.faces)
    rng = np.random.default_rng(seed)
    lo, hi = mesh.bounds
    points = np.vstack([rng.uniform(lo - 0.01, hi + 0.01, size=(200, 3)), rng.normal(scale=0.3, size=(20, 3))])
    exact = brute_distances(mesh.triangles, points)
    first = DistanceBounds.around(tree, lo - 0.01, hi + 0.01, spacing, 10**6)
    lower, upper = first.bounds(points)
    assert (lower <= exact + NUM_TOL).all() and (exact <= upper + NUM_TOL).all()
    inside = np.all((points >= lo - 0.01) & (points <= hi + 0.01), axis=1)
    assert (upper - lower)[inside].max() <= np.sqrt(3.0) * first.spacing + NUM_TOL
    second = DistanceBounds.around(tree, lo - 0.01, hi + 0.01, spacing, 10**6)
    order = rng.permutation(len(points))
    for half in np.array_split(order, 2):  # the other order, in two parts
        again = second.bounds(points[half])
        assert np.array_equal(again[0], lower[half]) and np.array_equal(again[1], upper[half])


def test_at_a_node_both_bounds_are_the_exact_distance() -> None:
    mesh = lumpy(1)
    tree = MeshDistance(mesh.vertices, mesh.faces)
    grid = DistanceBounds.around(tree, [-0.1, -0.1, -0.1], [0.1, 0.1, 0.1], 0.01, 10**6)
    nodes = grid.origin + np.array([[0, 0, 0], [3, 10, 7], [20, 20, 20]]) * grid.spacing
    lower, upper = grid.bounds(nodes)
    assert np.array_equal(lower, upper)
    assert np.allclose(lower, brute_distances(mesh.triangles, nodes), atol=NUM_TOL)


def test_a_large_box_gets_wider_spacing_not_more_nodes() -> None:
    grid = DistanceBounds.around(cube(), [-1.0, -2.0, -3.0], [1.0, 2.0, 3.0], 0.001, 50_000)
    assert np.prod(grid.shape) <= 50_000 and grid.spacing > 0.001
    last = grid.origin + (np.array(grid.shape) - 1) * grid.spacing  # the box is covered, not much more
    assert np.all(last >= [1.0, 2.0, 3.0]) and np.all(last - grid.spacing < [1.0, 2.0, 3.0])


def _bounds_reference(grid: DistanceBounds, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """DistanceBounds.bounds as it was before 2026-12-07 (np.clip, np.linalg.norm)."""
    query = np.asarray(points, float).reshape(-1, 3)
    cell = np.clip(np.rint((query - grid.origin) / grid.spacing), 0, np.array(grid.shape) - 1).astype(np.int64)
    value = grid.mesh.nearest(grid.origin + cell * grid.spacing).distance
    off = np.linalg.norm(query - (grid.origin + cell * grid.spacing), axis=1)
    return value - off, value + off


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(0.001, 0.02), st.integers(0, 300))
def test_the_grids_bounds_are_those_of_the_plain_way(seed: int, spacing: float, n: int) -> None:
    """Points inside the grid, on its nodes and far off it: the bounds of np.clip and np.linalg.norm, to the bit;
    a NaN point is refused as before."""
    mesh = lumpy(seed % 50)
    tree = MeshDistance(mesh.vertices, mesh.faces)
    rng = np.random.default_rng(seed)
    lo, hi = mesh.bounds
    grid = DistanceBounds.around(tree, lo - 0.01, hi + 0.01, spacing, 10**5)
    points = np.vstack([rng.uniform(lo - 0.02, hi + 0.02, size=(n, 3)) * 10.0 ** rng.uniform(-3, 1),
                        grid.origin + rng.integers(0, 5, size=(3, 3)) * grid.spacing])
    got, want = grid.bounds(points), _bounds_reference(grid, points)
    assert all(a.tobytes() == b.tobytes() for a, b in zip(got, want))
    with pytest.raises(ValueError), np.errstate(invalid="ignore"):
        grid.bounds(np.array([[np.nan, 0.0, 0.0]]))
