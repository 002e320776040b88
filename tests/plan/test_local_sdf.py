"""The measure local_sdf (planner/plan/local_sdf.py): the grid a hand declares
(hand.toml [local_sdf]; a broken table is a one-line error naming it), the
object's clipped signed distance at it against a box's known distances, and a
sweep that stores it for the Panda (read back as the stored pose gives it) and
not for a hand without a grid; a large mesh's collision proxy gives the cells
within the proxy's deviation; a mesh of overlapping bodies is sided by the
winding number (every cell inside either body reads inside); the Panda's
half turn maps its grid onto itself."""

from pathlib import Path

import numpy as np
import pytest
import trimesh
from helpers import refused_hand_toml
from hypothesis import given, settings
from hypothesis import strategies as st

from planner import api
from planner.db.store import open_db
from planner.geometry.distance import MeshDistance
from planner.plan.local_sdf import CLIP, DIGITS, LocalSurface, measure
from planner.plan.sweep import SweepSettings
from planner.specs.hand_spec import LOCAL_CELLS, LocalGrid
from planner.specs.hands import load_hand


def test_the_panda_declares_a_grid_the_barrett_none() -> None:
    grid = load_hand("panda").local_grid
    assert grid is not None and load_hand("barrett").local_grid is None
    points = grid.points()
    assert points.shape == (LOCAL_CELLS, 3)
    assert np.allclose(points.min(axis=0), grid.low) and np.allclose(points.max(axis=0), grid.high)
    # x slowest, z fastest: the first points differ in z only
    assert np.allclose(points[0, :2], points[1, :2]) and points[1, 2] > points[0, 2]


@pytest.mark.parametrize("table, message", [
    ("low = [0.03, -0.04, 0.05]\nhigh = [0.03, 0.04, 0.13]\ncounts = [3, 5, 5]", r"low must be below high"),
    ("low = [-0.03, -0.04, 0.05]\nhigh = [0.03, 0.04, 0.13]\ncounts = [3, 5, 4]", r"field 'counts'.*75"),
    ("low = [-0.03, -0.04, 0.05]\nhigh = [0.03, 0.04, 0.13]\ncounts = [3, 5, 5.5]", r"field 'counts'.*whole"),
    ("low = [-0.03, -0.04]\nhigh = [0.03, 0.04, 0.13]\ncounts = [3, 5, 5]", r"field 'low'.*3 numbers"),
])
def test_a_broken_grid_names_the_file_and_field(tmp_path: Path, table: str, message: str) -> None:
    refused_hand_toml(tmp_path, lambda text: text[:text.index("[local_sdf]")] + "[local_sdf]\n" + table + "\n",
                      message)


def _box_distance(points: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Exact signed distance to an axis-aligned box of half-extents ``half`` about the origin."""
    q = np.abs(points) - half
    outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
    return outside + np.minimum(q.max(axis=1), 0.0)


@settings(max_examples=15, deadline=None)
@given(st.floats(-0.05, 0.05), st.floats(-0.05, 0.05), st.floats(-0.12, -0.02), st.floats(-np.pi, np.pi))
def test_a_box_seen_from_the_hand(x: float, y: float, z: float, yaw: float) -> None:
    half = np.array([0.03, 0.02, 0.04])
    box = trimesh.creation.box(2 * half)
    grid = load_hand("panda").local_grid
    assert grid is not None
    pose = np.eye(4)
    c, s = np.cos(yaw), np.sin(yaw)
    pose[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
    pose[:3, 3] = [x, y, z]
    got = measure(grid, MeshDistance(box.vertices, box.faces), pose)
    points = grid.points() @ pose[:3, :3].T + pose[:3, 3]
    want = np.clip(_box_distance(points, half), -CLIP, CLIP)
    assert got.shape == (LOCAL_CELLS,)
    assert np.allclose(got, want, atol=0.5 * 10.0**-DIGITS + 1e-12)
    assert np.array_equal(got, np.round(got, DIGITS)) and np.abs(got).max() <= CLIP


def test_a_grid_spans_its_box_with_one_point_on_an_axis_in_the_middle() -> None:
    grid = LocalGrid((-1.0, 0.0, 0.0), (1.0, 1.0, 4.0), (1, 3, 25))
    points = grid.points()
    assert points.shape == (LOCAL_CELLS, 3) and np.allclose(points[:, 0], 0.0)
    assert np.allclose(np.unique(points[:, 2]), np.linspace(0.0, 4.0, 25))


def test_a_sweep_stores_it_for_the_panda_and_not_for_the_barrett(tmp_path: Path) -> None:
    db_path = tmp_path / "g.db"
    settings_ = SweepSettings(approaches=4, rolls=2)
    for hand in ("panda", "barrett"):
        api.generate(["box"], hand, db_path=db_path, settings=settings_, workers=1)
    db = open_db(db_path, create=False, readonly=True)
    panda = db.best("box", "panda", 1000, 0)
    barrett = db.best("box", "barrett", 1000, 0)
    assert panda and barrett
    assert all(g.measures.local_sdf is None for g in barrett)
    from planner.db.objects import stored_object

    surface = LocalSurface(load_hand("panda"), stored_object(db.object_row("box")).mesh)
    for g in panda[:20]:
        stored = g.measures.local_sdf
        assert stored is not None and stored.shape == (LOCAL_CELLS,)
        # the pose as stored (0.1 um) gives the same cells to the stored 0.1 mm
        assert np.allclose(surface.of(g.pose), stored, atol=1.01 * 10.0**-DIGITS)
    assert any((g.measures.local_sdf < 0).any() for g in panda)  # the box lies between the fingers


def test_a_large_meshs_proxy_gives_the_cells_within_its_deviation() -> None:
    import scanlike

    from planner import assets
    from planner.geometry.proxy import collision_proxy

    fine = scanlike.capsule(12_000)  # above the proxy's threshold (5,000 faces)
    key = assets.sha256_bytes(np.ascontiguousarray(fine.vertices).tobytes() + np.asarray(fine.faces).tobytes())
    proxy = collision_proxy(fine, key)
    assert not proxy.exact and len(proxy.mesh.faces) < len(fine.faces)
    hand = load_hand("panda")
    exact, coarse = LocalSurface(hand, fine), LocalSurface(hand, proxy.mesh)
    rng = np.random.default_rng(3)
    for _ in range(10):
        pose = np.eye(4)
        pose[:3, 3] = [*rng.normal(scale=0.01, size=2), -0.09 + rng.normal(scale=0.01)]
        a, b = exact.of(pose), coarse.of(pose)
        assert a is not None and b is not None
        assert np.abs(a - b).max() <= proxy.deviation + 10.0**-DIGITS


def test_overlapping_bodies_are_sided_by_the_winding_number() -> None:
    hand = load_hand("panda")
    grid = hand.local_grid
    assert grid is not None
    # a block across the jaw and a post along the approach, overlapping: one mesh of two closed bodies
    block = trimesh.creation.box((0.05, 0.05, 0.03))
    block.apply_translation([0.0, 0.0, 0.09])
    post = trimesh.creation.box((0.02, 0.02, 0.07))
    post.apply_translation([0.0, 0.0, 0.09])
    cells = LocalSurface(hand, trimesh.util.concatenate([block, post])).of(np.eye(4))
    assert cells is not None
    points = grid.points()
    inside = (np.all(np.abs(points - [0.0, 0.0, 0.09]) < [0.025, 0.025, 0.015], axis=1)
              | np.all(np.abs(points - [0.0, 0.0, 0.09]) < [0.01, 0.01, 0.035], axis=1))
    assert inside.any() and np.array_equal(cells < 0, inside)


def test_the_half_turn_of_the_panda_maps_its_grid_onto_itself() -> None:
    from dataclasses import replace

    hand = load_hand("panda")
    assert hand.roll_symmetry == 2 and load_hand("barrett").cell_turns == ()
    (turn,) = hand.cell_turns
    grid = hand.local_grid
    assert grid is not None
    points = grid.points()
    assert sorted(turn) == list(range(LOCAL_CELLS))
    assert np.allclose(points[list(turn)], points * [-1.0, -1.0, 1.0])  # half a turn about the approach, z
    lopsided = LocalGrid((-0.02, -0.04, 0.05), (0.03, 0.04, 0.13), (3, 5, 5))
    assert replace(hand, local_grid=lopsided).cell_turns == ()  # a grid the turn does not map onto itself


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_a_surface_keeps_its_grid_points_and_measures_as_the_grid_does(seed: int) -> None:
    """LocalSurface makes the grid's points once (not per grasp): the same cells, to the bit, as measuring with
    the grid's own points at any pose."""
    from scipy.spatial.transform import Rotation

    from planner.geometry.solid import load_object

    hand, mug = load_hand("panda"), load_object("mug").mesh
    local = LocalSurface(hand, mug)
    assert local.grid is not None and local.surface is not None
    pose = np.eye(4)
    pose[:3, :3] = Rotation.random(random_state=seed).as_matrix()
    pose[:3, 3] = np.random.default_rng(seed).uniform(-0.05, 0.05, 3)
    assert np.array_equal(local.of(pose), measure(local.grid, local.surface, pose))
    assert np.array_equal(local.points, local.grid.points()) and not local.points.flags.writeable


@settings(max_examples=10, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 6))
def test_cells_read_together_are_each_poses_own_to_the_bit(seed: int, count: int) -> None:
    """``measured_together`` (the sweep's waiting grasps, one query of the object): each pose's cells as
    ``LocalSurface.of`` reads them alone, bit for bit, in order; None where nothing was asked or the hand has no
    grid."""
    from scipy.spatial.transform import Rotation

    from planner.geometry.solid import load_object
    from planner.plan.local_sdf import measured_together

    mug = load_object("mug").mesh
    local, barrett = LocalSurface(load_hand("panda"), mug), LocalSurface(load_hand("barrett"), mug)
    rng = np.random.default_rng(seed)
    poses = []
    for _ in range(count):
        pose = np.eye(4)
        pose[:3, :3] = Rotation.random(random_state=rng).as_matrix()
        pose[:3, 3] = rng.uniform(-0.08, 0.08, 3)
        poses.append(pose)
    asked = [(local, p) for p in poses] + [None, (barrett, poses[0])]
    got = measured_together(asked)
    assert got[-2:] == [None, None]
    for pose, cells in zip(poses, got):
        assert cells is not None and cells.tobytes() == local.of(pose).tobytes()  # type: ignore[union-attr]
