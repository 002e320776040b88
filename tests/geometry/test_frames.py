"""Frames and rotations: contact frames, the hand's rotation, poses, angles."""

from __future__ import annotations

import numpy as np
from helpers import NUM_TOL, assert_close
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from planner.geometry import frames

unit = st.lists(st.floats(-1, 1), min_size=3, max_size=3).map(np.array).filter(lambda v: np.linalg.norm(v) > 0.1)


@settings(max_examples=200, deadline=None)
@given(a=unit, d=unit, roll=st.floats(-7, 7))
def test_hand_rotation_maps_approach_onto_direction(a: np.ndarray, d: np.ndarray, roll: float) -> None:
    r = frames.hand_rotation(a, d, roll)
    assert_close(r @ r.T, np.eye(3), 1e-9)
    assert np.linalg.det(r) > 0
    assert_close(r @ (a / np.linalg.norm(a)), d / np.linalg.norm(d), 1e-9)


@settings(max_examples=200, deadline=None)
@given(a=unit, d=unit, roll=st.floats(-3, 3))
def test_hand_rotation_is_the_scipy_composition_and_roll_about_inverts_it(a: np.ndarray, d: np.ndarray,
                                                                         roll: float) -> None:
    """The closed-form roll of hand_rotation is Rotation.from_rotvec(roll * d)
    applied after the fixed frame change, to round-off."""
    a_u, d_u = a / np.linalg.norm(a), d / np.linalg.norm(d)
    base = frames.contact_frames(d_u)[0] @ frames.contact_frames(a_u)[0].T
    expected = (Rotation.from_rotvec(roll * d_u) * Rotation.from_matrix(base)).as_matrix()
    rotation = frames.hand_rotation(a, d, roll)
    assert_close(rotation, expected, NUM_TOL)
    assert_close(frames.roll_about(rotation, a, d), roll, 1e-9)


def _hand_rotation_reference(approach: np.ndarray, direction: np.ndarray, roll: float) -> np.ndarray:
    """hand_rotation as written before 2026-12-07: both frames made anew and the spin multiplied in at any roll."""
    a, d = approach / np.linalg.norm(approach), direction / np.linalg.norm(direction)
    base = frames.contact_frames(d)[0] @ frames.contact_frames(a)[0].T
    c, s = np.cos(roll), np.sin(roll)
    k = np.array([[0, -d[2], d[1]], [d[2], 0, -d[0]], [-d[1], d[0], 0]])
    return (np.eye(3) + s * k + (1 - c) * (k @ k)) @ base


@settings(max_examples=300, deadline=None)
@given(a=unit, d=unit | st.sampled_from([np.eye(3)[i] * sign for i in range(3) for sign in (1.0, -1.0)]),
       roll=st.sampled_from([0.0, -0.0]) | st.floats(-3, 3))
def test_hand_rotation_is_the_full_formulas_to_the_bit(a: np.ndarray, d: np.ndarray, roll: float) -> None:
    """The approach's frame made once and no spin at roll 0: every entry (the sign of a zero too) as the full
    formula gives it, so every pose and roll stored before comes out the same."""
    got, want = frames.hand_rotation(a, d, roll), _hand_rotation_reference(a, d, roll)
    assert np.array_equal(got, want) and np.array_equal(np.signbit(got), np.signbit(want))


@settings(max_examples=100, deadline=None)
@given(normals=st.lists(unit, min_size=1, max_size=8))
def test_contact_frames_are_right_handed_with_the_normal_first(normals: list) -> None:
    n = np.array([v / np.linalg.norm(v) for v in normals])
    r = frames.contact_frames(n)
    assert_close(r[:, :, 0], n, NUM_TOL)
    assert_close(np.einsum("nki,nkj->nij", r, r), np.broadcast_to(np.eye(3), r.shape), NUM_TOL)
    assert_close(np.linalg.det(r), np.ones(len(n)), NUM_TOL)
    l_vec, o_vec = frames.tangent_bases(n)
    assert_close(r[:, :, 1], l_vec) and assert_close(r[:, :, 2], o_vec)
    for i, v in enumerate(n):  # batched = one at a time, bit for bit
        assert np.array_equal(frames.contact_frames(v)[0], r[i])


def test_tilted_directions_keep_the_tilt_angle() -> None:
    d = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
    for phi in (0.0, 1.0, 4.0):
        t = frames.tilted(d, 0.3, phi)
        assert_close(np.linalg.norm(t, axis=1), [1.0, 1.0], NUM_TOL)
        assert_close(np.einsum("ij,ij->i", t, d), np.cos([0.3, 0.3]), NUM_TOL)


def test_pose_from_xyzquat_and_angle_between() -> None:
    quarter = frames.pose_from_xyzquat([1.0, 2.0, 3.0, 0.0, 0.0, np.sin(np.pi / 4), np.cos(np.pi / 4)])
    assert_close(quarter[:3, 3], [1.0, 2.0, 3.0])
    assert_close(quarter[:3, :3] @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], NUM_TOL)
    assert_close(frames.angle_between(np.eye(3), quarter[:3, :3]), np.pi / 2, NUM_TOL)
    assert_close(frames.angle_between(quarter[:3, :3], quarter[:3, :3]), 0.0, NUM_TOL)
    turn = frames.rotation_from_rotvec([0.0, 0.0, 0.25])
    assert_close(frames.angle_between(np.eye(3), turn), 0.25, NUM_TOL)


@settings(max_examples=100, deadline=None)
@given(a=unit, b=unit)
def test_rotation_onto_takes_one_direction_onto_another(a: np.ndarray, b: np.ndarray) -> None:
    r = frames.rotation_onto(a, b)
    assert_close(r @ (a / np.linalg.norm(a)), b / np.linalg.norm(b), 1e-9)


@settings(max_examples=50, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(0, 30))
def test_rows_cross_is_numpys_cross_to_the_bit(seed: int, n: int) -> None:
    """Random rows, unit axes, zeros of both signs and huge and tiny magnitudes: the same bits as ``np.cross``."""
    rng = np.random.default_rng(seed)
    pool = np.array([0.0, -0.0, 1.0, -1.0, 1e-300, 1e300, np.pi])
    a = np.where(rng.random((n, 3)) < 0.3, rng.choice(pool, (n, 3)), rng.normal(size=(n, 3)))
    b = np.where(rng.random((n, 3)) < 0.3, rng.choice(pool, (n, 3)), rng.normal(size=(n, 3)))
    with np.errstate(over="ignore", invalid="ignore"):
        got, want = frames.rows_cross(a, b), np.cross(a, b).reshape(-1, 3)
    assert got.shape == want.shape and got.tobytes() == want.tobytes()


@settings(max_examples=100, deadline=None)
@given(angle=st.floats(-3, 3), step=st.floats(-1e-9, 1e-9))
def test_same_poses_matches_equal_values_whatever_their_sign_of_zero_or_rounding(angle: float, step: float) -> None:
    """An import compared rounded bytes: -0.0 is not 0.0 there, and 0.1234549999 and 0.1234550001 round apart."""
    pose = np.eye(4)
    pose[:3, :3] = Rotation.from_rotvec([0, 0, angle]).as_matrix()
    pose[:3, 3] = [0.0, 0.123455, 0.0]
    again = pose + step
    again[again == 0] = -0.0  # as `transforms @ inv(export_frame)` gives
    other = pose.copy()
    other[0, 3] += 2 * frames.SAME_POSE_TOL
    assert list(frames.same_poses(np.stack([again, other]), pose[None])) == [True, False]
    assert not frames.same_poses(pose[None], np.empty((0, 4, 4))).any()
