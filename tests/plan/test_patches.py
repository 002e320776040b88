"""Contact patches: a flat pad on a box face is an area (>= 3 non-collinear
contacts, force closure), the legacy point reading stays available, small
regions become soft fingers, extreme points of a rectangle are its corners,
the cells' short cut finds the samples near the object that measuring every
sample finds, a link's own neighbour pairs are those of its moved samples."""

import numpy as np
import pytest
import trimesh
from helpers import NUM_TOL, SIM_TOL, brute_distances
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from planner.geometry.solid import load_object
from planner.plan.closing import Closed, CloseSettings, Grasper
from planner.plan.contacts import HandContacts, contact_models
from planner.plan.patches import (
    BOX_MARGIN,
    ObjectSurface,
    PatchSettings,
    Region,
    _band,
    _band_reference,
    _cluster,
    _components_reference,
    _norms,
    _plane,
    discretise,
    extreme_points,
    hand_surfaces,
    link_regions,
)
from planner.plan.patches import _components as patch_components
from planner.plan.unit import grasp_quality
from planner.sim import Sim
from planner.specs.hands import load_hand
from planner.specs.preshapes import load_preshapes

DOWN = np.array([0.0, 0.0, -1.0])


@pytest.fixture(scope="module")
def box_pinch() -> tuple[Closed, Closed]:
    """The Panda from above the 5 x 4 x 8 cm box, fingers on its 4 cm faces:
    read as patches and the legacy way."""
    hand, obj = load_hand("panda"), load_object("box")
    wide = {s.name: s for s in load_preshapes(hand)}["wide"]
    out = []
    for reading in ("patch", "points"):
        with Sim() as sim:
            g = Grasper.for_mesh(sim, hand, obj.mesh, CloseSettings(contacts=reading))
            closed = g.close(np.array([0, 0, 0.04]), DOWN, 0.0, 0.02, wide, obj.torque_scale)
        assert isinstance(closed, Closed)
        out.append(closed)
    return out[0], out[1]


def rank(points: np.ndarray) -> int:
    return int(np.linalg.matrix_rank(points - points.mean(axis=0), tol=1e-4))


def test_a_flat_pad_on_a_box_face_is_a_patch_of_non_collinear_contacts_in_force_closure(box_pinch) -> None:  # type: ignore[no-untyped-def]
    patch, _ = box_pinch
    hand, obj = load_hand("panda"), load_object("box")
    for finger in ("panda_leftfinger", "panda_rightfinger"):
        mine = np.array(patch.contacts.links) == finger
        assert mine.sum() >= 3 and rank(patch.contacts.points[mine]) == 2  # a plane patch, not a line
        assert np.allclose(np.abs(patch.contacts.points[mine, 1]), 0.02, atol=SIM_TOL)
        assert (np.abs(patch.contacts.normals[mine, 1]) > np.cos(np.radians(10))).all()  # about the face normal
        assert (patch.contacts.radius[mine] == 0).all() and len(set(patch.contacts.region[mine])) == 1
    assert grasp_quality(patch.contacts, hand, obj, 8).force_closure


def test_the_legacy_point_reading_is_kept(box_pinch) -> None:  # type: ignore[no-untyped-def]
    patch, points = box_pinch
    assert np.isnan(points.contacts.radius).all() and (points.contacts.region == -1).all()
    assert "radius" not in points.contacts.json_text()
    assert patch.closed_joints == points.closed_joints  # only the reading differs
    restored = HandContacts.stored(patch.contacts.json_text(), len(patch.contacts), patch.contacts.touching)
    assert np.allclose(restored.radius, patch.contacts.radius) and (restored.region == patch.contacts.region).all()


def test_a_links_legacy_points_are_read_only_where_its_patch_comes_out_empty(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """Every touching link with a patch: no legacy point reading at all; a link whose patch comes out empty
    keeps the very points the legacy reading gives it, the other its patch."""
    import planner.plan.contact_reading as reading

    hand, obj = load_hand("panda"), load_object("box")
    wide = {s.name: s for s in load_preshapes(hand)}["wide"]
    calls, legacy, regions = [], reading.ContactReading._points, reading.regions
    monkeypatch.setattr(reading.ContactReading, "_points", lambda self, *a: calls.append(1) or legacy(self, *a))

    def closed(contacts: str) -> Closed:
        with Sim() as sim:
            g = Grasper.for_mesh(sim, hand, obj.mesh, CloseSettings(contacts=contacts))
            out = g.close(np.array([0, 0, 0.04]), DOWN, 0.0, 0.02, wide, obj.torque_scale)
        assert isinstance(out, Closed)
        return out

    assert len(closed("patch").contacts) > 2 and calls == []
    monkeypatch.setattr(reading, "regions", lambda *args: [r for r in regions(*args) if r.link != "panda_rightfinger"])
    kept, points = closed("patch").contacts, closed("points").contacts
    assert calls == [1, 1]  # the empty patch's fallback, then the legacy reading itself
    right, legacy_right = (np.array(c.links) == "panda_rightfinger" for c in (kept, points))
    assert right.sum() == legacy_right.sum() > 0
    assert np.array_equal(kept.points[right], points.points[legacy_right])
    assert np.array_equal(kept.normals[right], points.normals[legacy_right])
    assert (kept.radius[~right] == 0).all() and (kept.region[~right] >= 0).all() and np.isnan(kept.radius[right]).all()


def test_extreme_points_of_a_rectangle_are_its_corners() -> None:
    x, y = np.meshgrid(np.linspace(-0.01, 0.01, 21), np.linspace(-0.005, 0.005, 11))
    pts = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    got = pts[extreme_points(pts, np.array([0.0, 0.0, 1.0]), 4)]
    assert sorted(map(tuple, np.round(np.abs(got[:, :2]), 6))) == [(0.01, 0.005)] * 4
    assert len({tuple(p) for p in np.round(got, 6)}) == 4


def test_a_small_region_is_one_soft_contact_with_torsion_from_its_size() -> None:
    hand = load_hand("panda")
    pts = np.array([[0.0, 0.0, 0.0], [0.001, 0.0, 0.0], [0.0, 0.001, 0.0]])
    normal = np.array([0.0, 0.0, 1.0])
    region = Region("panda_leftfinger", pts, np.tile(normal, (3, 1)), area=np.pi * 0.002**2, diameter=0.0015,
                    normal=normal)
    contacts = discretise([region], PatchSettings())
    assert len(contacts) == 1 and contacts.radius[0] == pytest.approx(0.002)
    models, torsion = contact_models(contacts, hand, 0.5)
    assert models == ["soft"] and torsion[0] == pytest.approx(2 / 3 * 0.5 * 0.002)
    palm = discretise([Region("panda_hand", pts, np.tile(normal, (3, 1)), 1e-6, 0.0015, normal)], PatchSettings())
    assert contact_models(palm, hand, 0.5)[0] == ["point"]  # the palm is not soft


@settings(max_examples=40, deadline=None)
@given(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0), st.floats(-1.0, 1.0), st.floats(0.0, 2 * np.pi),
       st.floats(-0.01, 0.03))
def test_the_cell_bounded_band_is_the_band_of_every_sample(x: float, y: float, z: float, angle: float,
                                                          lift: float) -> None:
    """The samples near the object that the cells find are those that measuring
    every sample finds, the finger placed anywhere near the box's top face
    (touching, tilted, far)."""
    hand, obj = load_hand("panda"), load_object("box")
    surface = ObjectSurface(obj.mesh)
    finger = hand_surfaces(hand, surface.settings)["panda_leftfinger"]
    axis = np.array([x, y, z]) if np.linalg.norm([x, y, z]) > 1e-3 else np.array([0.0, 0.0, 1.0])
    pose = np.eye(4)
    pose[:3, :3] = Rotation.from_rotvec(axis / np.linalg.norm(axis) * angle).as_matrix()
    pose[:3, 3] = [0.0, 0.0, obj.mesh.bounds[1, 2] + lift]
    points = finger.points @ pose[:3, :3].T + pose[:3, 3]
    lo, hi = obj.mesh.bounds - np.array([[BOX_MARGIN], [-BOX_MARGIN]])
    idx = np.flatnonzero(np.all((points > lo) & (points < hi), axis=1))
    band, (closest, distance, face) = _band(finger, pose, points, idx, surface)
    assert np.array_equal(band, _band_reference(points, idx, surface))
    want = surface.nearest(points[band])
    assert all(np.array_equal(a, b) for a, b in zip((closest, distance, face), want))


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from(["box", "mug"]))
def test_closest_points_are_the_nearest_of_every_face(seed: int, name: str) -> None:
    """The object's closest points are the nearest of all its faces' closest
    points (every face tried), for points near the surface, on its edges and
    vertices (where faces tie: the distance agrees) and farther out; on the
    box, a signed gap whose closest point lies inside a face is negative
    inside the box and positive outside (the mug's walls are thinner than
    the points' spread: trimesh's ``contains`` is no oracle there)."""
    surface = ObjectSurface(load_object(name).mesh)
    mesh = surface.mesh
    rng = np.random.default_rng(seed)
    near, _ = trimesh.sample.sample_surface(mesh, 200, seed=seed)
    points = np.vstack([near + rng.normal(scale=0.002, size=near.shape),  # a few mm off the surface
                        mesh.vertices[rng.integers(len(mesh.vertices), size=50)],  # on vertices: faces tie
                        mesh.vertices[mesh.edges[rng.integers(len(mesh.edges), size=50)]].mean(axis=1),  # edges
                        mesh.centroid + rng.normal(scale=0.05, size=(20, 3))])
    closest, distance, face = surface.nearest(points)
    want = brute_distances(mesh.triangles, points)
    assert np.allclose(distance, want, rtol=0, atol=NUM_TOL)
    assert np.allclose(np.linalg.norm(closest - points, axis=1), distance, rtol=0, atol=NUM_TOL)
    on_face = [brute_distances(mesh.triangles[f][None], c[None])[0] for f, c in zip(face, closest)]
    assert np.allclose(on_face, 0.0, atol=NUM_TOL)  # the closest point lies on the face said
    if name != "box":
        return
    gap = surface.closest(points)[1]
    interior = (trimesh.triangles.points_to_barycentric(mesh.triangles[face], closest) > 1e-6).all(axis=1)
    sure = interior & (want > 1e-4)
    contained = mesh.contains(points)
    assert sure.sum() > 100
    assert (gap[sure & contained] < 0).all() and (gap[sure & ~contained] > 0).all()


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(0.0005, 0.004))
def test_a_links_own_pairs_are_the_pairs_of_its_moved_samples(seed: int, radius: float) -> None:
    """Any subset of a finger's samples, moved anywhere: the pairs kept from the
    link's own are the pairs a tree of the moved subset finds."""
    finger = hand_surfaces(load_hand("panda"), PatchSettings())["panda_leftfinger"]
    rng = np.random.default_rng(seed)
    idx = np.sort(rng.choice(len(finger.points), size=int(rng.integers(2, 400)), replace=False))
    rotation = Rotation.random(random_state=seed).as_matrix()
    moved = finger.points[idx] @ rotation.T + rng.normal(scale=0.1, size=3)
    want = {tuple(p) for p in cKDTree(moved).query_pairs(radius * (1 - 1e-9), output_type="ndarray")}
    wide = {tuple(p) for p in cKDTree(moved).query_pairs(radius * (1 + 1e-9), output_type="ndarray")}
    got = {tuple(p) for p in finger.pairs_among(idx, radius)}
    assert want <= got <= wide  # the same pairs (up to round-off at exactly the radius)
    assert all(a < b for a, b in got)


def _components(count: int, pairs: np.ndarray) -> np.ndarray:
    """(count,) labels of the connected components of ``pairs`` (p, 2), numbered in the order of their smallest
    member: a plain union-find."""
    parent = list(range(count))

    def root(i: int) -> int:
        while parent[i] != i:
            i = parent[i]
        return i

    for a, b in pairs:
        ra, rb = root(int(a)), root(int(b))
        parent[max(ra, rb)] = min(ra, rb)
    return np.unique([root(i) for i in range(count)], return_inverse=True)[1].reshape(-1)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(0.0005, 0.004), st.floats(0.0, np.pi))
def test_regions_are_the_components_of_close_samples_of_similar_normals(seed: int, radius: float,
                                                                       split: float) -> None:
    """The regions of any subset of a finger's samples with normals spread about one direction, from the link's own
    pairs or a tree's: the components of the pairs whose normals differ by less than the split angle."""
    finger = hand_surfaces(load_hand("panda"), PatchSettings())["panda_leftfinger"]
    rng = np.random.default_rng(seed)
    idx = np.sort(rng.choice(len(finger.points), size=int(rng.integers(2, 400)), replace=False))
    normals = rng.normal(size=(len(idx), 3)) * rng.uniform(0.0, 2.0) + [0.0, 0.0, 1.0]
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    points = finger.points[idx]
    for pairs in (finger.pairs_among(idx, radius), None):
        close = cKDTree(points).query_pairs(radius, output_type="ndarray") if pairs is None else pairs
        similar = close[np.einsum("ij,ij->i", normals[close[:, 0]], normals[close[:, 1]]) > np.cos(split)]
        assert np.array_equal(_cluster(points, normals, radius, split, pairs), _components(len(idx), similar))


def _outside_cone(point: np.ndarray, normal: np.ndarray, half: np.ndarray) -> float:
    """[rad] how far an inward ``normal`` at ``point`` on an axis-aligned box of half extents ``half`` lies outside
    the box's normal cone there (the inward normals of the faces the point is on, and their combinations)."""
    from scipy.optimize import nnls

    on = [(a, s) for a in range(3) for s in (-1.0, 1.0) if abs(point[a] - s * half[a]) < 1e-4]
    cone = np.array([[-s * float(i == a) for i in range(3)] for a, s in on]).T
    return float(np.arcsin(min(nnls(cone, normal)[1], 1.0)))


@pytest.mark.parametrize("hand, approaches", [("pr2", 64), ("barrett", 24)])
def test_contact_normals_at_the_boxs_edges_are_normals_the_box_has_there(hand: str, approaches: int) -> None:
    """A link touching a box edge with its side or rim gave the side's normal: a
    PR2 fingertip on a vertical edge pushed the box straight down (0, 0.15,
    -0.99), 83 of the PR2's and 124 of the Barrett's edge contacts were 45
    degrees or more outside the box's normals there, and force closure came
    from them. Point contacts on an edge or corner now lie in its normal cone;
    a soft contact at a small region's centre has the region's mean normal
    (within 15 degrees of the cone where a region spans an edge and a corner)."""
    from planner.plan.sweep import SweepSettings
    from planner.plan.unit import UnitSpec, run_unit

    half = np.array(load_object("box").mesh.extents) / 2
    settings = SweepSettings(approaches=approaches, rolls=2, reach_placements=0, settle=False)
    result = run_unit(UnitSpec("box", hand, settings, seed=0))
    edges = [(_outside_cone(p, n, half), r > 0) for g in result.grasps for p, n, r in
             zip(g.contacts.points, g.contacts.normals, g.contacts.radius)
             if sum(abs(abs(p) - half) < 1e-4) >= 2]
    assert len(edges) > 100
    assert max(angle for angle, soft in edges if not soft) < np.radians(0.5)
    assert max(angle for angle, _ in edges) < np.radians(15)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 300), st.floats(0.0, 8.0))
def test_the_components_are_scipys_connected_components(seed: int, n: int, degree: float) -> None:
    """Any graph, isolated nodes and none of its edges included: the same labels (numbered by their smallest
    node) and dtype as scipy's public connected_components of its CSR graph."""
    rng = np.random.default_rng(seed)
    pairs = np.sort(rng.integers(0, n, size=(int(degree * n / 2), 2)), axis=1)
    pairs = np.unique(pairs[pairs[:, 0] < pairs[:, 1]], axis=0).reshape(-1, 2)  # ascending by the first node
    got, want = patch_components(n, pairs), _components_reference(n, pairs)
    assert got.dtype == want.dtype and np.array_equal(got, want)


def _extreme_points_reference(points: np.ndarray, normal: np.ndarray, limit: int) -> np.ndarray:
    """extreme_points as it was before a region kept its plane coordinates (2026-12-06)."""
    from planner.plan.patches import _DIRS

    uv = _plane(points, normal)
    proj = uv @ _DIRS.T
    hull = np.unique(np.r_[np.argmax(proj, axis=0), np.argmin(proj, axis=0)])
    v = uv[hull]
    chosen = [int(np.argmax(np.linalg.norm(v, axis=1)))]
    dist = np.linalg.norm(v - v[chosen[0]], axis=1)
    while len(chosen) < min(limit, len(v)):
        k = int(np.argmax(dist))
        if dist[k] <= 1e-9:
            break
        chosen.append(k)
        dist = np.minimum(dist, np.linalg.norm(v - v[k], axis=1))
    return hull[chosen]


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 400), st.integers(1, 6))
def test_extreme_points_from_a_regions_plane_are_those_from_its_points(seed: int, k: int, limit: int) -> None:
    """The extreme points read from the plane coordinates a region keeps are those of projecting its points
    again, as the code before did (np.linalg.norm's lengths to the bit)."""
    rng = np.random.default_rng(seed)
    points = rng.normal(size=(k, 3)) * rng.uniform(1e-4, 1e-2, size=3)
    normal = rng.normal(size=3)
    normal /= np.linalg.norm(normal)
    want = _extreme_points_reference(points, normal, limit)
    assert np.array_equal(extreme_points(points, normal, limit), want)
    assert np.array_equal(extreme_points(points, normal, limit, _plane(points, normal)), want)
    v = rng.normal(size=(k, 2)) * 10.0 ** rng.uniform(-6, 2)
    assert np.array_equal(_norms(v), np.linalg.norm(v, axis=1))


def test_a_regions_plane_and_diameter_are_its_points_in_its_tangent_plane(box_pinch) -> None:  # type: ignore[no-untyped-def]
    """A region's plane coordinates are its points' (None for a single point) and its diameter their widest
    extent along the 32 directions, as measured before the region kept them."""
    from planner.plan.patches import _DIRS

    hand, obj = load_hand("panda"), load_object("box")
    surfaces, surface = hand_surfaces(hand, PatchSettings()), ObjectSurface(obj.mesh)
    patch, _ = box_pinch
    found = [r for link, pose in patch.link_poses.items() if link in surfaces
             for r in link_regions(link, surfaces[link], pose, surface)]
    assert found
    for r in found:
        if len(r.points) < 2:
            assert r.plane is None and r.diameter == 0.0
            continue
        assert np.array_equal(r.plane, _plane(r.points, r.normal))
        proj = _plane(r.points, r.normal) @ _DIRS.T
        assert r.diameter == float(np.max(proj.max(axis=0) - proj.min(axis=0)))


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from(["box", "mug"]))
def test_features_found_once_are_those_found_again_for_any_rows(seed: int, name: str) -> None:
    """A patch's contact normals read the features (face, edge or vertex) that its signed gaps found, not found
    again for the band's sharp points: a subset's features are the whole set's rows bit for bit, and so are the
    normals (points on faces, edges and vertices of the box and the mug; a random subset kept, as the band)."""
    surface = ObjectSurface(load_object(name).mesh)
    mesh, rng = surface.mesh, np.random.default_rng(seed)
    near, _ = trimesh.sample.sample_surface(mesh, 150, seed=seed)
    corners = rng.choice(np.flatnonzero(surface.sharp_vertex), 40)  # sharp: the normals read their features
    points = np.vstack([near + rng.normal(scale=0.001, size=near.shape), mesh.vertices[corners],
                        mesh.vertices[mesh.edges[rng.integers(len(mesh.edges), size=40)]].mean(axis=1)])
    closest, gap, normal, smooth, feature = surface.signed_features(points, *surface.nearest(points))
    assert all(np.array_equal(a, b) for a, b in zip((closest, gap, normal, smooth), surface.closest(points)))
    keep = rng.random(len(points)) < 0.6
    again = surface._feature(closest[keep], surface.nearest(points)[2][keep])
    assert all(np.array_equal(getattr(feature.take(keep), k), getattr(again, k)) for k in ("count", "first", "last"))
    assert (~smooth[keep]).sum() > 3  # sharp points, whose features the normals read
    face = surface.nearest(points)[2][keep]
    toward = -normal[keep]
    assert np.array_equal(surface.contact_normals(closest[keep], face, smooth[keep], toward, feature.take(keep)),
                          surface.contact_normals(closest[keep], face, smooth[keep], toward))


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 400), st.integers(0, 3000))
def test_pairs_ordered_by_node_give_the_components_of_any_order(seed: int, n: int, count: int) -> None:
    """``_by_node``: a stable ascending order of small node indices (a radix sort where they fit 16 bits); the
    components of pairs so ordered are those of scipy's connected_components (numbered by their smallest node)."""
    from planner.plan import patches

    rng = np.random.default_rng(seed)
    first = rng.integers(0, n, count)
    order = patches._by_node(first, n)
    assert order.tobytes() == np.argsort(first, kind="stable").tobytes()
    pairs = np.column_stack([first, rng.integers(0, n, count)])[order]
    assert np.array_equal(patches._components(n, pairs), patches._components_reference(n, pairs))


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(0, 500))
def test_samples_in_the_box_a_coordinate_at_a_time_are_those_of_all_at_once(seed: int, k: int) -> None:
    """Points inside, outside, on a face of the box (bounds excluded) and NaN: the rows the (k, 3) comparison keeps."""
    from planner.plan.patches import _in_box

    rng = np.random.default_rng(seed)
    low, high = rng.uniform(-0.1, 0.0, 3), rng.uniform(0.0, 0.1, 3)
    points = rng.uniform(-0.15, 0.15, (k, 3))
    on = rng.random((k, 3)) < 0.1
    points[on] = np.where(rng.random(int(on.sum())) < 0.5, np.broadcast_to(low, (k, 3))[on],
                          np.broadcast_to(high, (k, 3))[on])
    points[rng.random((k, 3)) < 0.02] = np.nan
    within = (points > low) & (points < high)
    assert np.array_equal(_in_box(points, low, high), np.flatnonzero(within.all(axis=1)))
