"""The poses an object rests in on a table (trimesh's quasi-static estimate).

``grasp best OBJECT --on-table`` places the object in its most probable
resting poses instead of asking the user for one. trimesh drops the object's
convex hull onto a plane from its centre of mass and estimates how often it
comes to rest on each hull face; with no noise it is deterministic.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import trimesh


@dataclass(frozen=True)
class RestingPose:
    """One resting pose.

    Attributes:
        pose: (4, 4) the object frame in the world: the object lies on the
            table top z = 0 with its centre of mass above (x, y) = (0, 0) [m].
        probability: trimesh's estimate of how often it rests so, in [0, 1].
    """

    pose: np.ndarray
    probability: float

    def __post_init__(self) -> None:
        if self.pose.shape != (4, 4):
            raise ValueError("RestingPose.pose must be (4, 4)")

    def placed(self, x: float, y: float, table_height: float) -> np.ndarray:
        """(4, 4) the pose moved to (x, y) on a table top at ``table_height`` [m]."""
        out = self.pose.copy()
        out[:3, 3] += [x, y, table_height]
        return out


def resting_poses(mesh: trimesh.Trimesh, centre_of_mass: np.ndarray, limit: int = 3) -> list[RestingPose]:
    """The ``limit`` most probable resting poses, most probable first."""
    import trimesh  # noqa: F811 - heavy: imported where it is used

    transforms, probabilities = trimesh.poses.compute_stable_poses(mesh, center_mass=np.asarray(centre_of_mass, float))
    order = np.argsort(-np.asarray(probabilities), kind="stable")[:limit]
    out = []
    for i in order:
        pose = np.asarray(transforms[i], float).copy()
        pose[:2, 3] -= (pose[:3, :3] @ centre_of_mass + pose[:3, 3])[:2]  # trimesh leaves it a few mm off
        out.append(RestingPose(pose, float(probabilities[i])))
    return out
