"""The table under an object, in the object's own frame.

A grasp planned "on the table" is planned with the table top as an obstacle
(:mod:`planner.plan.closing`): the plane ``normal . x = height`` of the object
frame, the table filling the side the normal points away from. The plane is
all that matters to the hand: the same object resting the same way anywhere
on the table, turned about the vertical by any angle, has the same plane in
its frame, so grasps planned with it are free of the table at every such
placement (only the arm's reach changes).

- :meth:`Support.under`: the plane of a table top at world height ``h``
  under an object at a given pose;
- :meth:`Support.resting`: the plane of one of the object's resting poses
  (:mod:`planner.geometry.stable`);
- :func:`nearest`: of stored planes, the one a query's plane is (the same
  normal within :data:`SAME_NORMAL`, the nearest height).

Lengths in metres, angles in radians.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

#: A plane normal must be unit length within this (a stored one is rounded to 1e-7).
UNIT_TOL = 1e-5
#: A query's table and a stored one are the same resting pose when their
#: normals are this close: a pose read from a camera is a degree or two off
#: the resting pose it is in.
SAME_NORMAL = float(np.radians(3.0))


@dataclass(frozen=True)
class Support:
    """A table top under an object.

    Attributes:
        normal: (3,) unit vector, object frame: up, out of the table.
        height: [m] the table top is the plane ``normal . x = height`` of the
            object frame; the table fills ``normal . x < height``.
    """

    normal: np.ndarray
    height: float

    def __post_init__(self) -> None:
        normal = np.asarray(self.normal, float)
        if normal.shape != (3,) or not np.all(np.isfinite(normal)) or abs(np.linalg.norm(normal) - 1) > UNIT_TOL:
            raise ValueError(f"Support.normal must be a (3,) unit vector, got {self.normal}")
        if not np.isfinite(self.height):
            raise ValueError(f"Support.height must be finite, got {self.height}")
        object.__setattr__(self, "normal", normal / np.linalg.norm(normal))
        object.__setattr__(self, "height", float(self.height))

    @classmethod
    def under(cls, object_pose: np.ndarray, table_height: float = 0.0) -> Support:
        """The table top at world z = ``table_height`` [m] under an object
        whose frame is at ``object_pose`` (4, 4) in the world (z up)."""
        rotation, position = object_pose[:3, :3], object_pose[:3, 3]
        return cls(rotation.T @ np.array([0.0, 0.0, 1.0]), table_height - float(position[2]))

    @classmethod
    def resting(cls, resting_pose: np.ndarray) -> Support:
        """The table top z = 0 of a resting pose (:class:`planner.geometry.stable.RestingPose`)."""
        return cls.under(resting_pose, 0.0)

    @classmethod
    def from_vector(cls, values: ArrayLike) -> Support:
        """From its stored form (:meth:`vector`)."""
        v = np.asarray(values, float)
        if v.shape != (4,):
            raise ValueError(f"a stored support is (4,) [nx, ny, nz, height], got shape {v.shape}")
        return cls(v[:3], float(v[3]))

    def vector(self) -> np.ndarray:
        """(4,) [nx, ny, nz, height]: how the database stores it (``grasps.table_plane``)."""
        return np.r_[self.normal, self.height]

    def raised(self, by: float) -> Support:
        """The plane moved ``by`` [m] up (out of the table)."""
        return Support(self.normal, self.height + by)

    def frame(self) -> np.ndarray:
        """(4, 4) a frame on the table top, object frame: its z axis the
        normal, its origin the point of the plane nearest the object origin."""
        pose = np.eye(4)
        pose[:3, :3] = upright(self.normal).T
        pose[:3, 3] = self.normal * self.height
        return pose

    def from_below(self, directions: ArrayLike) -> np.ndarray:
        """(n,) bool: which unit approach directions (n, 3), object frame,
        move the hand up, out of the table (the hand would come from under
        the table top's level)."""
        return np.atleast_2d(np.asarray(directions, float)) @ self.normal > UNIT_TOL

    def steepened(self, directions: ArrayLike, elevation: float) -> np.ndarray:
        """(n, 3) the unit approach directions (n, 3), object frame, each
        coming down onto the table at least ``elevation`` [rad] below the
        plane's level: a shallower one is turned down in its vertical plane
        to exactly ``elevation``; steeper ones, and those from below
        (:meth:`from_below`), are left as they are."""
        d = np.atleast_2d(np.asarray(directions, float)).copy()
        down = d @ self.normal
        level = d - down[:, None] * self.normal
        length = np.linalg.norm(level, axis=1)
        shallow = (down > -np.sin(elevation)) & (down <= UNIT_TOL) & (length > UNIT_TOL)
        d[shallow] = (np.cos(elevation) * level[shallow] / length[shallow, None]
                      - np.sin(elevation) * self.normal)
        return d

    def angle_to(self, other: Support) -> float:
        """[rad] between the two normals."""
        return float(np.arccos(np.clip(self.normal @ other.normal, -1.0, 1.0)))


def nearest(planes: Sequence[np.ndarray], support: Support, normal_tol: float = SAME_NORMAL) -> np.ndarray | None:
    """Of stored planes (each (4,), :meth:`Support.vector`), the one whose
    normal is within ``normal_tol`` [rad] of ``support``'s and whose height is
    nearest; None if no normal is that close."""
    same = [p for p in planes if Support.from_vector(p).angle_to(support) <= normal_tol]
    return min(same, key=lambda p: abs(float(p[3]) - support.height), default=None)


def upright(normal: ArrayLike) -> np.ndarray:
    """(3, 3) the smallest rotation taking the unit ``normal`` (object frame)
    to the world's +z: the object turned so that the table is under it."""
    n = np.asarray(normal, float)
    if n[2] < -0.5:  # nearer straight down: turn half a turn about x first, then the small rest
        flip = np.diag([1.0, -1.0, -1.0])
        return upright(flip @ n) @ flip
    # Rodrigues with the unnormalised axis v = n x z (|v| = sin, n . z = cos): exact down to v = 0
    v = np.cross(n, [0.0, 0.0, 1.0])
    skew = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return np.eye(3) + skew + skew @ skew / (1.0 + n[2])
