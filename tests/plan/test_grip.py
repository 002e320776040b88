"""Grip measures (planner.plan.grip): the Panda closed on boxes, plates and an
edge with known answers, and invariance under a rigid motion of object and
grasp together."""

import numpy as np
import pytest
import trimesh
from helpers import assert_close
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from planner.geometry.frames import UP, resting_up
from planner.plan import grip, link_hulls
from planner.plan.closing import Closed, Grasper
from planner.sim import Sim
from planner.specs.hands import load_hand
from planner.specs.preshapes import load_preshapes

#: [m^2] one coarse sample's worth of area at the default spacing (areas are sample counts x area).
AREA_TOL = 4e-6 * 6
#: [m] palm_gap reads 2 mm samples: within one spacing of the exact gap.
GAP_TOL = 0.0025


@pytest.fixture(scope="module")
def panda():  # type: ignore[no-untyped-def]
    hand = load_hand("panda")
    return hand, hand.widest(load_preshapes(hand))


def centred_pose(rotation: np.ndarray | None = None) -> np.ndarray:
    """The Panda's hand frame with its tool centre point at the object's origin."""
    pose = np.eye(4)
    pose[:3, :3] = np.eye(3) if rotation is None else rotation
    pose[:3, 3] = -pose[:3, :3] @ np.array([0.0, 0.0, 0.1034])
    return pose


def closed_grip(panda, mesh: trimesh.Trimesh, pose: np.ndarray) -> tuple[Closed, grip.Grip]:  # type: ignore[no-untyped-def]
    hand, shape = panda
    with Sim() as sim:
        closed = Grasper.for_mesh(sim, hand, mesh).close_at(pose, shape, 0.05)
    assert isinstance(closed, Closed)
    surface = grip.GripSurface(mesh)
    return closed, grip.measure(hand, surface, closed.contacts, closed.link_poses or {}, mesh.center_mass)


def moved_grip(panda, mesh: trimesh.Trimesh, closed: Closed, motion: np.ndarray,  # type: ignore[no-untyped-def]
               up: np.ndarray = UP) -> grip.Grip:
    """The grip of ``closed`` with object and hand both moved by ``motion`` (4, 4) (the samples redrawn),
    the object's up as it rests ``up`` (3,) in the moved frame."""
    moved = mesh.copy()
    moved.apply_transform(motion)
    links = {k: motion @ v for k, v in (closed.link_poses or {}).items()}
    contacts = type(closed.contacts)(closed.contacts.points @ motion[:3, :3].T + motion[:3, 3],
                                     closed.contacts.normals @ motion[:3, :3].T, closed.contacts.links)
    return grip.measure(panda[0], grip.GripSurface(moved), contacts, links, moved.center_mass, up)


def test_pads_flat_on_a_box_face_each_other_and_the_palm_gap_is_the_box_top(panda) -> None:  # type: ignore[no-untyped-def]
    box = trimesh.creation.box((0.03, 0.04, 0.06))  # 4 cm across the fingers (hand y), 6 cm along the approach
    closed, g = closed_grip(panda, box, centred_pose())
    assert g.pad_area > 1e-4  # > 100 mm^2 of face under each pad
    assert g.pad_alignment > 0.97 and g.opposition > 0.99
    # the pads touch the box from its top (3 cm above the tcp, toward the palm) to the fingertips: the centre of
    # mass lies on the closing axis, below the line through the pad centres by half the tip's overhang
    finger = closed.link_poses["panda_leftfinger"]  # type: ignore[index]
    tip = float((grip.hulls(panda[0])["panda_leftfinger"].vertices @ finger[:3, :3].T + finger[:3, 3])[:, 2].max())
    assert g.com_lever == pytest.approx(abs((-0.03 + tip) / 2), abs=GAP_TOL)
    palm_front = grip.hulls(panda[0])["panda_hand"].vertices[:, 2].max()
    assert g.palm_gap == pytest.approx(0.1034 - 0.03 - palm_front, abs=GAP_TOL)


def test_where_the_weight_sits_about_the_grip_from_below_and_from_the_side(panda) -> None:  # type: ignore[no-untyped-def]
    # from below (approach +z): the pads' midpoint lies on the vertical through the centre of mass, at the
    # height com_lever says; the axis (y) is horizontal and passes under it, so the weight has no lever
    _, below = closed_grip(panda, trimesh.creation.box((0.03, 0.04, 0.06)), centred_pose())
    assert abs(below.com_height) == pytest.approx(below.com_lever, abs=1e-3)
    assert below.gravity_arm == pytest.approx(0.0, abs=1e-3)
    # from the side (approach +x, the same box turned): the midpoint is beside the centre of mass at its height,
    # and the weight's lever about the horizontal axis is the whole offset
    side = centred_pose(Rotation.from_euler("y", 90, degrees=True).as_matrix())
    _, beside = closed_grip(panda, trimesh.creation.box((0.06, 0.04, 0.03)), side)
    assert beside.com_height == pytest.approx(0.0, abs=1e-3)
    assert beside.gravity_arm == pytest.approx(beside.com_lever, abs=1e-3)
    assert beside.gravity_arm == pytest.approx(below.com_lever, abs=GAP_TOL)
    # the axis vertical (fingers closing along z): no lever, whatever the offset
    upright = centred_pose(Rotation.from_euler("x", 90, degrees=True).as_matrix())
    _, vertical = closed_grip(panda, trimesh.creation.box((0.03, 0.06, 0.04)), upright)
    assert vertical.gravity_arm == pytest.approx(0.0, abs=1e-3)
    assert vertical.com_lever > 0.005


def test_the_weight_measures_turn_only_with_the_vertical(panda) -> None:  # type: ignore[no-untyped-def]
    mesh = trimesh.creation.capsule(height=0.04, radius=0.018, count=[16, 16])
    pose = centred_pose(Rotation.from_euler("xy", [30, 60], degrees=True).as_matrix())  # tilted both ways
    pose[:3, 3] -= pose[:3, 2] * 0.012  # backed off along the approach: the pads hold it off its centre of mass
    closed, base = closed_grip(panda, mesh, pose)
    rng = np.random.default_rng(11)
    for _ in range(3):  # about the vertical and shifted: the same; tilted: the height changes
        motion = np.eye(4)
        motion[:3, :3] = Rotation.from_euler("z", rng.uniform(0, 360), degrees=True).as_matrix()
        motion[:3, 3] = rng.uniform(-0.2, 0.2, 3)
        again = moved_grip(panda, mesh, closed, motion)
        assert again.com_height == pytest.approx(base.com_height, abs=1e-4)
        assert again.gravity_arm == pytest.approx(base.gravity_arm, abs=1e-4)
    assert abs(base.com_height) > 1e-3 and base.gravity_arm > 1e-3


def test_on_a_table_the_weight_measures_read_the_tables_up(panda) -> None:  # type: ignore[no-untyped-def]
    """An object resting in another pose (a table's up, object frame): turned with object and grasp, the up turns
    with them and the weight measures stay; read about the object's own +z instead, they change."""
    mesh = trimesh.creation.capsule(height=0.04, radius=0.018, count=[16, 16])
    pose = centred_pose(Rotation.from_euler("xy", [30, 60], degrees=True).as_matrix())
    pose[:3, 3] -= pose[:3, 2] * 0.012
    closed, base = closed_grip(panda, mesh, pose)
    rng = np.random.default_rng(5)
    for _ in range(3):
        motion = np.eye(4)
        motion[:3, :3] = Rotation.random(random_state=rng).as_matrix()
        table = np.r_[motion[:3, :3] @ UP * 2.0, -0.01]  # a table plane (up, offset): the up need not be unit
        again = moved_grip(panda, mesh, closed, motion, resting_up(table))
        assert again.com_height == pytest.approx(base.com_height, abs=1e-4)
        assert again.gravity_arm == pytest.approx(base.gravity_arm, abs=1e-4)
        plain = moved_grip(panda, mesh, closed, motion)
        assert abs(plain.com_height - base.com_height) + abs(plain.gravity_arm - base.gravity_arm) > 1e-3
    assert np.array_equal(resting_up(None), UP)


def test_two_walls_fill_the_jaw_more_than_a_block_under_the_same_pads(panda) -> None:  # type: ignore[no-untyped-def]
    _, block = closed_grip(panda, trimesh.creation.box((0.03, 0.04, 0.06)), centred_pose())
    walls = trimesh.util.concatenate([trimesh.creation.box((0.03, 0.002, 0.06)).apply_translation((0, y, 0))
                                      for y in (-0.019, 0.019)])  # a hollow 4 cm body: its far walls lie inside
    _, hollow = closed_grip(panda, walls, centred_pose())
    assert hollow.pad_area == pytest.approx(block.pad_area, abs=AREA_TOL * 3)  # both outer faces cover the pads
    assert hollow.jaw_fill > 1.25 * block.jaw_fill  # the walls' inner faces add to the pads' outer ones


def test_an_edge_between_the_pads_is_a_sliver_at_45_degrees(panda) -> None:  # type: ignore[no-untyped-def]
    box = trimesh.creation.box((0.03, 0.03, 0.06))
    _, face = closed_grip(panda, box, centred_pose())
    _, edge = closed_grip(panda, box, centred_pose(Rotation.from_euler("z", 45, degrees=True).as_matrix()))
    assert edge.pad_area < 0.3 * face.pad_area
    assert edge.pad_alignment == pytest.approx(np.cos(np.pi / 4), abs=0.05)


def test_grip_is_invariant_under_a_rigid_motion_of_object_and_grasp(panda) -> None:  # type: ignore[no-untyped-def]
    mesh = trimesh.creation.capsule(height=0.04, radius=0.018, count=[16, 16])
    pose = centred_pose(Rotation.from_euler("x", 90, degrees=True).as_matrix())
    closed, base = closed_grip(panda, mesh, pose)
    rng = np.random.default_rng(7)
    for _ in range(3):  # seeded motions: the samples are redrawn on the moved mesh, so counts may differ by a few
        motion = np.eye(4)
        motion[:3, :3] = Rotation.random(random_state=rng).as_matrix()
        motion[:3, 3] = rng.uniform(-0.2, 0.2, 3)
        again = moved_grip(panda, mesh, closed, motion)
        assert_close(np.array([again.pad_alignment, again.opposition]),
                     np.array([base.pad_alignment, base.opposition]), 0.02)
        assert_close(np.array([again.pad_area, again.jaw_fill]), np.array([base.pad_area, base.jaw_fill]), AREA_TOL)
        assert again.palm_gap == pytest.approx(base.palm_gap, abs=GAP_TOL)
        assert again.com_lever == pytest.approx(base.com_lever, abs=1e-4)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), band=st.floats(0.0005, 0.01))
def test_early_exit_hull_tests_equal_the_full_ones(seed: int, band: float) -> None:
    """The block-wise hull tests (faces read 32 at a time, points dropped on
    the way) give the points, distances and faces of testing every face."""
    from scipy.spatial import ConvexHull

    rng = np.random.default_rng(seed)
    cloud = rng.normal(size=(60, 3))
    cloud = cloud / np.linalg.norm(cloud, axis=1, keepdims=True) * [0.04, 0.02, 0.06]  # every point a vertex:
    # an ellipsoid's hull of 60 vertices has 116 faces, several blocks of 32
    hull = ConvexHull(cloud)
    shape = grip.Hull(hull.points[hull.vertices], hull.equations[:, :3].copy(), -hull.equations[:, 3].copy())
    pose = np.eye(4)
    pose[:3, :3] = Rotation.random(random_state=seed).as_matrix()
    pose[:3, 3] = rng.normal(size=3) * 0.01
    points = rng.normal(size=(2000, 3)) * 0.04
    idx = np.arange(len(points))
    near, dist, face = grip._near(shape, pose, points, idx, band)
    full, full_face = grip._distance(shape, pose, points)
    expected = np.flatnonzero(full < band)
    assert len(shape.normals) > 32 and len(expected) > 0
    assert np.array_equal(near, expected)
    assert np.array_equal(face, full_face[expected]) and np.allclose(dist, full[expected], rtol=0, atol=1e-15)
    surface = grip.GripSurface(trimesh.creation.icosphere(subdivisions=3, radius=0.03))
    corners = shape.vertices @ pose[:3, :3].T + pose[:3, 3]
    inside = grip._inside(corners, surface)
    outer = ConvexHull(corners).equations
    everything = np.flatnonzero(np.all(surface.coarse @ outer[:, :3].T + outer[:, 3] <= 0.0, axis=1))
    assert len(everything) > 0 and np.array_equal(np.sort(inside), everything)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), faces=st.integers(1, 60), repeats=st.integers(0, 40))
def test_planes_without_repeats_equal_the_reference(seed: int, faces: int, repeats: int) -> None:
    """Planes repeated in any order, ties in leading coordinates and signed zeros included: the same rows in the
    same order (first occurrences) as np.unique's."""
    rng = np.random.default_rng(seed)
    planes = rng.normal(size=(faces, 4))
    planes[rng.random((faces, 4)) < 0.2] = 0.0
    planes[rng.random((faces, 4)) < 0.1] = -0.0
    planes[:, 0] = np.where(rng.random(faces) < 0.5, planes[0, 0], planes[:, 0])
    equations = np.vstack([planes, planes[rng.integers(0, faces, repeats)]])[rng.permutation(faces + repeats)]
    got, want = link_hulls.planes(equations), link_hulls.planes_reference(equations)
    assert got.tobytes() == want.tobytes()


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), half=st.floats(0.0, 0.04), coarse=st.booleans())
def test_box_query_equals_the_reference(seed: int, half: float, coarse: bool) -> None:
    """The column-wise box query gives the reference's indices, boxes on sample coordinates included (their bounds
    are inclusive)."""
    surface = grip.GripSurface(trimesh.creation.box((0.06, 0.04, 0.08)))
    rng = np.random.default_rng(seed)
    points = surface.coarse if coarse else surface.points
    centre = points[rng.integers(len(points))]
    lo, hi = centre - half * rng.random(3), centre + half * rng.random(3)
    if rng.random() < 0.5:  # a box whose faces pass through samples
        lo, hi = np.minimum(lo, points[rng.integers(len(points))]), np.maximum(hi, points[rng.integers(len(points))])
        lo[0], hi[2] = points[rng.integers(len(points)), 0], points[rng.integers(len(points)), 2]
    got, want = surface.box(lo, hi, coarse), surface.box_reference(lo, hi, coarse)
    assert np.array_equal(got, want)
    assert np.all((points[got] >= lo) & (points[got] <= hi))


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), spread=st.floats(0.0, 0.03))
def test_inside_and_palm_gap_equal_the_plain_tests_on_a_meshed_hand(seed: int, spread: float) -> None:
    """On the Barrett's hulls (meshed: qhull repeats a flat face's plane on each of its triangles), the repeats
    dropped, the inner polytope's shortcut and the palm gap's early exit give what testing every sample against
    every face gives: the same samples inside, bit for bit, and the same smallest distance to the palm, to its
    last bits (hypothesis found a palm 1 ulp away: the products' blocking depends on how many rows they have)."""
    from scipy.spatial import ConvexHull

    hand = load_hand("barrett")
    shapes = grip.hulls(hand)
    rng = np.random.default_rng(seed)
    finger = shapes["bh_finger_32_link"]
    assert len(finger.normals) < len(ConvexHull(finger.vertices).equations)  # repeats were dropped
    poses = []
    for _ in range(3):  # three finger tips spread about the object, seeded
        pose = np.eye(4)
        pose[:3, :3] = Rotation.random(random_state=rng).as_matrix()
        pose[:3, 3] = rng.normal(size=3) * spread
        poses.append(pose)
    corners = np.vstack([finger.vertices @ p[:3, :3].T + p[:3, 3] for p in poses])
    surface = grip.GripSurface(trimesh.creation.icosphere(subdivisions=3, radius=0.03))
    inside = grip._inside(corners, surface)
    outer = ConvexHull(corners).equations
    everything = np.flatnonzero(np.all(surface.coarse @ outer[:, :3].T + outer[:, 3] <= 0.0, axis=1))
    assert np.array_equal(inside, everything)
    palm = np.eye(4)
    palm[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    palm[:3, 3] = rng.normal(size=3) * 0.03
    subset = np.sort(rng.choice(len(surface.coarse), size=200, replace=False))
    for chosen in (inside, subset):
        if not len(chosen):
            continue
        plain = np.clip(grip._distance(shapes[hand.root_link], palm, surface.coarse[chosen])[0].min(), 0.0, 0.05)
        # the early exit multiplies fewer rows: BLAS may block the product otherwise, moving the last bit
        assert grip._palm_gap(hand, shapes, {hand.root_link: palm}, surface, chosen) == pytest.approx(plain, rel=1e-14,
                                                                                                   abs=1e-16)
        every = ConvexHull(shapes[hand.root_link].vertices).equations  # every triangle's plane, repeats and all
        local = (surface.coarse[chosen] - palm[:3, 3]) @ palm[:3, :3]
        assert plain == pytest.approx(np.clip((local @ every[:, :3].T + every[:, 3]).max(axis=1).min(), 0.0, 0.05),
                                      abs=1e-12)


def test_the_pandas_fingers_take_every_plane_without_an_inner_polytope(monkeypatch: pytest.MonkeyPatch) -> None:
    """Two Panda fingers' hull has few planes (at most INNER_PLANES): one qhull (the fingers' hull), no inner
    polytope's, and the samples every plane keeps, bit for bit."""
    from scipy.spatial import ConvexHull

    hand = load_hand("panda")
    shapes = grip.hulls(hand)
    apart = np.eye(4)
    apart[1, 3] = 0.03
    corners = np.vstack([shapes["panda_leftfinger"].vertices,
                         shapes["panda_rightfinger"].vertices @ apart[:3, :3].T + apart[:3, 3]])
    surface = grip.GripSurface(trimesh.creation.icosphere(subdivisions=3, radius=0.03))
    outer = ConvexHull(corners).equations
    assert len(link_hulls.planes(outer)) <= grip.INNER_PLANES
    built = []
    monkeypatch.setattr(grip, "ConvexHull", lambda points: built.append(len(points)) or ConvexHull(points))
    inside = grip._inside(corners, surface)
    everything = np.flatnonzero(np.all(surface.coarse @ outer[:, :3].T + outer[:, 3] <= 0.0, axis=1))
    assert built == [len(corners)] and len(everything) > 0 and np.array_equal(inside, everything)
