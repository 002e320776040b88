"""Frames and rotations, all through ``scipy.spatial.transform.Rotation``.

- :func:`tangent_bases` / :func:`contact_frames`: for n unit normals at once,
  the tangents (l_i, o_i) and the contact frames R_i = (n_i, l_i, o_i) of
  grasping-foundations sec. 2.2. The tangents are a fixed function of the
  normal (l = n x e, e the first of x, y not nearly parallel to n), so a
  contact frame, and with it the friction-cone edges, never depends on how
  the contact was found.
- :func:`hand_rotation`: the hand frame's rotation for an approach direction
  and a roll about it.
- :func:`pose_from_xyzquat`: a 4x4 pose from position and quaternion
  (x, y, z, w), the form a user types.
- :func:`angle_between`: the angle [rad] of the rotation from one frame to
  another.
- :func:`same_poses`: which poses equal one of a set, entry by entry within
  :data:`SAME_POSE_TOL`.

Poses are 4x4 homogeneous matrices, lengths in metres, angles in radians.
(The PyBullet adapter converts poses for the simulator itself, per move, with
a cheaper routine: see :func:`planner.sim.pose_to_pb`.)
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

#: The object frame's +z: the up of an object nobody gave another (:data:`planner.specs.up.DEFAULT_UP`; an object's
#: own is ``PreparedObject.up``). An object rests and is lifted with its weight along -up (the MuJoCo trial's
#: default gravity, ``MujocoSettings.down = "-z"``; the grip measures ``com_height`` and ``gravity_arm``), or
#: along the table's down where a grasp was planned on a table (:func:`resting_up`).
UP = np.array([0.0, 0.0, 1.0])


def resting_up(table_plane: np.ndarray | None, up: np.ndarray = UP) -> np.ndarray:
    """(3,) unit: the object's up as it rests, object frame: the table's up for a grasp planned on a table
    (``Grasp.table_plane``: its first three entries; the table's up wins), else the object's own ``up`` (3,)
    (``PreparedObject.up``; :data:`UP` unless told)."""
    if table_plane is None:
        return up
    up = np.asarray(table_plane, float)[:3]
    return up / np.linalg.norm(up)


#: |n_x| below this: the tangent helper axis is x, else y (well conditioned).
HELPER_SWITCH = 0.9
_X, _Y = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])


def tangent_bases(normals: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """(l, o), each (n, 3): unit tangents with (n_i, l_i, o_i) right-handed
    and orthonormal, for (n, 3) unit normals."""
    n = np.asarray(normals, float).reshape(-1, 3)
    helper = np.where((np.abs(n[:, 0]) < HELPER_SWITCH)[:, None], _X, _Y)
    l_vec = rows_cross(n, helper)
    l_vec /= np.sqrt(np.einsum("ij,ij->i", l_vec, l_vec))[:, None]
    return l_vec, rows_cross(n, l_vec)


def rows_cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(n, 3) the cross products of the rows of ``a`` and ``b`` (n, 3): ``np.cross(a, b)`` to the bit (the same
    products and differences), without its broadcasting set-up, which costs more than the arithmetic on a few
    rows."""
    out = np.empty(a.shape)
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


def contact_frames(normals: ArrayLike) -> np.ndarray:
    """(n, 3, 3) contact frames R_i with columns (n_i, l_i, o_i)."""
    n = np.asarray(normals, float).reshape(-1, 3)
    l_vec, o_vec = tangent_bases(n)
    return np.stack([n, l_vec, o_vec], axis=2)


def tilted(directions: ArrayLike, angle: float, phi: float) -> np.ndarray:
    """(n, 3) unit directions tilted by ``angle`` [rad] away from each of the
    (n, 3) unit ``directions``, towards azimuth ``phi`` [rad] in its tangent plane."""
    d = np.asarray(directions, float).reshape(-1, 3)
    l_vec, o_vec = tangent_bases(d)
    return np.cos(angle) * d + np.sin(angle) * (np.cos(phi) * l_vec + np.sin(phi) * o_vec)


def hand_rotation(approach_hand: ArrayLike, direction: ArrayLike, roll: float) -> np.ndarray:
    """(3, 3) rotation of the hand frame: maps ``approach_hand`` (hand frame)
    onto ``direction`` (object frame), then rolls by ``roll`` [rad] about
    ``direction``. Deterministic for any input.

    A fixed frame per vector (not the minimal rotation) so that roll 0 means
    the same thing for every direction: frame(a) -> frame(d).

    The one rotation not built by ``Rotation``: the roll is applied in closed
    form (Rodrigues), as when the grasps in existing databases were planned.
    ``Rotation.from_rotvec`` gives the same matrix to ~1e-15, but closing
    turns that into ~5e-6 rad of finger travel on some grasps (a contact
    decided one step earlier), so switching needs an ``ALGORITHM_VERSION``
    bump; a test checks the two agree."""
    a = np.asarray(approach_hand, float)
    d = np.asarray(direction, float)
    a, d = a / np.linalg.norm(a), d / np.linalg.norm(d)
    base = contact_frames(d)[0] @ _frame(a.tobytes()).T
    if roll == 0.0:  # the spin is the identity, whose product is base with its -0.0 made 0.0: so is this, bit for bit
        return base + 0.0
    c, s = np.cos(roll), np.sin(roll)
    k = np.array([[0, -d[2], d[1]], [d[2], 0, -d[0]], [-d[1], d[0], 0]])
    spin = np.eye(3) + s * k + (1 - c) * (k @ k)
    return spin @ base


@lru_cache(maxsize=16)
def _frame(unit: bytes) -> np.ndarray:
    """(3, 3) :func:`contact_frames` of one unit vector given by its bytes (a hand's approach axis: the same for
    every grasp of the hand, made once)."""
    frame = contact_frames(np.frombuffer(unit))[0]
    frame.flags.writeable = False
    return frame


def roll_about(rotation: np.ndarray, approach_hand: ArrayLike, direction: ArrayLike) -> float:
    """The roll [rad], in (-pi, pi], with ``hand_rotation(approach_hand,
    direction, roll) == rotation``: the inverse of :func:`hand_rotation`."""
    d = np.asarray(direction, float)
    d = d / np.linalg.norm(d)
    spin = Rotation.from_matrix(rotation @ hand_rotation(approach_hand, d, 0.0).T)
    return float(spin.as_rotvec() @ d)


def pose_from_xyzquat(values: ArrayLike) -> np.ndarray:
    """4x4 pose from (x, y, z, qx, qy, qz, qw)."""
    v = np.asarray(values, float)
    pose = np.eye(4)
    pose[:3, :3] = Rotation.from_quat(v[3:]).as_matrix()
    pose[:3, 3] = v[:3]
    return pose


def rotation_from_rotvec(rotvec: ArrayLike) -> np.ndarray:
    """(3, 3) rotation by |rotvec| [rad] about the direction of ``rotvec`` (3,)."""
    return Rotation.from_rotvec(np.asarray(rotvec, float)).as_matrix()


def rotation_onto(a: ArrayLike, b: ArrayLike) -> np.ndarray:
    """(3, 3) smallest rotation taking the direction ``a`` onto ``b``."""
    rotation, _ = Rotation.align_vectors(np.atleast_2d(b), np.atleast_2d(a))
    return rotation.as_matrix()


def angle_between(a: np.ndarray, b: np.ndarray) -> float:
    """Angle [rad] of the rotation taking frame ``a`` to frame ``b`` ((3, 3) each)."""
    return float((Rotation.from_matrix(a).inv() * Rotation.from_matrix(b)).magnitude())


def approach_of(pose: np.ndarray, approach_hand: ArrayLike, tcp: ArrayLike) -> tuple[np.ndarray, np.ndarray, float]:
    """The approach ray of a hand pose: (point (3,) [m], unit direction (3,),
    roll [rad]) in the object frame, for ``pose`` (4, 4) the hand frame in the
    object frame, ``approach_hand`` the hand's approach axis and ``tcp`` the
    point [m] (hand frame) the approach ray passes through: the preshape's
    (:attr:`planner.specs.preshapes.Preshape.tcp`, by default the hand's)."""
    rotation = pose[:3, :3]
    direction = rotation @ approach_hand
    return rotation @ tcp + pose[:3, 3], direction, roll_about(rotation, approach_hand, direction)


#: Largest difference [m, or unitless for the rotation] in any entry of two poses that are one pose: 10 um, far
#: above what a file's round trip changes (float32 transforms, an export frame multiplied in and out, the store's
#: 7 decimals) and far below two planned grasps' spacing. Entries are compared as numbers, not as rounded bytes:
#: -0.0 is 0.0, and two values a hair apart never fall on either side of a rounding boundary.
SAME_POSE_TOL = 1e-5


def same_poses(poses: np.ndarray, among: np.ndarray, tol: float = SAME_POSE_TOL) -> np.ndarray:
    """(n,) bool: which of ``poses`` (n, 4, 4) has every entry within ``tol`` of one of ``among`` (m, 4, 4)."""
    poses, among = np.asarray(poses, float), np.asarray(among, float)
    if not len(poses) or not len(among):
        return np.zeros(len(poses), bool)
    gap, _ = cKDTree(among[:, :3].reshape(len(among), 12)).query(poses[:, :3].reshape(len(poses), 12), p=np.inf)
    return gap <= tol
