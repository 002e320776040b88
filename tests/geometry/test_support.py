"""The table under an object, in the object's frame (planner.geometry.support)."""

import numpy as np
import pytest
from helpers import NUM_TOL, assert_close
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from planner.geometry.support import SAME_NORMAL, Support, nearest, upright

#: A random rigid pose: a rotation from 4 numbers (normalised) and a position [m].
poses = st.tuples(st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(lambda q: np.linalg.norm(q) > 0.1),
                  st.lists(st.floats(-1, 1), min_size=3, max_size=3))


def pose_of(q: list[float], t: list[float]) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = Rotation.from_quat(q).as_matrix()
    out[:3, 3] = t
    return out


@given(poses, st.floats(-0.5, 0.5))
@settings(max_examples=60, deadline=None)
def test_the_plane_is_the_table_top_seen_from_the_object(pose: tuple, height: float) -> None:
    """Points of the object frame on the plane are at the table's height in the world; above it, higher."""
    world = pose_of(*pose)
    s = Support.under(world, height)
    on_plane = s.frame() @ np.array([[0.3, -0.2, 0.0, 1.0], [-0.1, 0.4, 0.0, 1.0], [0.0, 0.0, 0.0, 1.0]]).T
    assert_close((world @ on_plane)[2], np.full(3, height), 1e-8)
    above = s.frame() @ np.array([0.0, 0.0, 0.05, 1.0])
    assert (world @ above)[2] == pytest.approx(height + 0.05, abs=1e-9)


@given(poses)
@settings(max_examples=60, deadline=None)
def test_upright_turns_the_normal_up_and_the_vector_round_trips(pose: tuple) -> None:
    s = Support.under(pose_of(*pose), 0.1)
    assert_close(upright(s.normal) @ s.normal, [0.0, 0.0, 1.0], 1e-9)
    assert_close(np.linalg.det(upright(s.normal)), 1.0, 1e-9)
    back = Support.from_vector(s.vector())
    assert_close(back.vector(), s.vector(), NUM_TOL)


def test_upright_of_straight_down_is_a_proper_rotation() -> None:
    assert_close(upright([0.0, 0.0, -1.0]) @ [0.0, 0.0, -1.0], [0.0, 0.0, 1.0])
    assert_close(np.linalg.det(upright([0.0, 0.0, -1.0])), 1.0)


def test_approaches_from_below_and_shallow_ones_steepened() -> None:
    s = Support(np.array([0.0, 0.0, 1.0]), -0.02)
    d = np.array([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, np.sqrt(0.5), -np.sqrt(0.5)],
                  [np.sqrt(0.75), 0.0, 0.5]])
    assert s.from_below(d).tolist() == [False, False, True, False, True]
    steep = s.steepened(d, np.radians(30))
    assert_close(np.linalg.norm(steep, axis=1), np.ones(5))
    assert_close(steep[1], [np.cos(np.radians(30)), 0.0, -0.5])  # level: turned down, same heading
    for kept in (0, 2, 3, 4):  # already steep enough, or from below (left for from_below to refuse)
        assert_close(steep[kept], d[kept])


def test_the_nearest_stored_plane_has_the_same_normal() -> None:
    up, side = Support(np.array([0.0, 0.0, 1.0]), -0.04), Support(np.array([1.0, 0.0, 0.0]), -0.025)
    planes = [side.vector(), up.vector(), up.raised(0.02).vector()]
    tilted = Support(Rotation.from_euler("x", SAME_NORMAL / 2).as_matrix() @ up.normal, -0.035)
    assert_close(nearest(planes, tilted), up.vector())
    assert nearest(planes, Support(Rotation.from_euler("x", 2 * SAME_NORMAL).as_matrix() @ up.normal, -0.04)) is None


def test_a_bad_plane_is_refused() -> None:
    with pytest.raises(ValueError, match="unit vector"):
        Support(np.array([0.0, 0.0, 2.0]), 0.0)
    with pytest.raises(ValueError, match="finite"):
        Support(np.array([0.0, 0.0, 1.0]), float("nan"))
