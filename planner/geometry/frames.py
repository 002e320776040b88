"""Frames and rotations: the hand's rotation for an approach direction and
roll, tangent bases of contact normals, pose <-> position and quaternion,
the angle between two rotations."""

from __future__ import annotations

import numpy as np


def tangent_basis(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (l, o) with (n, l, o) a right-handed orthonormal frame."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    l_vec = np.cross(n, helper)
    l_vec /= np.linalg.norm(l_vec)
    return l_vec, np.cross(n, l_vec)


def tilt(direction: np.ndarray, angle: float, phi: float) -> np.ndarray:
    l_vec, o_vec = tangent_basis(direction)
    return np.cos(angle) * direction + np.sin(angle) * (np.cos(phi) * l_vec + np.sin(phi) * o_vec)


def hand_rotation(approach_hand: np.ndarray, direction: np.ndarray, roll: float) -> np.ndarray:
    """(3, 3) rotation of the hand frame: maps ``approach_hand`` onto ``direction``,
    then rolls by ``roll`` [rad] about ``direction``. Deterministic for any input."""
    a = approach_hand / np.linalg.norm(approach_hand)
    d = direction / np.linalg.norm(direction)
    # A fixed frame per vector (not the minimal rotation) so that roll 0 means
    # the same thing for every direction: frame(a) -> frame(d).
    la, oa = tangent_basis(a)
    ld, od = tangent_basis(d)
    base = np.column_stack([d, ld, od]) @ np.column_stack([a, la, oa]).T
    c, s = np.cos(roll), np.sin(roll)
    k = np.array([[0, -d[2], d[1]], [d[2], 0, -d[0]], [-d[1], d[0], 0]])
    spin = np.eye(3) + s * k + (1 - c) * (k @ k)
    return spin @ base


def pose_from_xyzquat(values: tuple[float, ...]) -> np.ndarray:
    """4x4 pose from (x, y, z, qx, qy, qz, qw)."""
    import trimesh.transformations as tf

    x, y, z, qx, qy, qz, qw = values
    pose = tf.quaternion_matrix([qw, qx, qy, qz])
    pose[:3, 3] = (x, y, z)
    return pose


def angle_between(a: np.ndarray, b: np.ndarray) -> float:
    cos = (np.trace(a.T @ b) - 1.0) / 2.0
    return float(np.arccos(np.clip(cos, -1.0, 1.0)))
