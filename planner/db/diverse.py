"""Diverse top-K: grasps at least a stated pose distance apart, and how much of
the object their contacts cover.

The distance between two grasps is measured between their tool centre
points (``HandSpec.tcp``, the point between the fingers) and between their
orientations; a hand that looks the same after a turn of ``2 pi / s`` about
its approach axis (``roll_symmetry`` s: the Panda's two fingers swap places
at pi) counts those turns as the same grasp. Selection is greedy in rank
order: a grasp is kept when it is at least ``translation`` metres OR
``rotation`` radians from every grasp kept so far, so the best grasp is
always first and each kept grasp is the best of its neighbourhood.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from planner.record.grasp import Grasp

DEFAULT_TRANSLATION = 0.02  # [m] two grasps whose centres are this far apart are different
DEFAULT_ROTATION = np.radians(30.0)  # [rad] ... or whose orientations differ by this much
COVERAGE_RADIUS = 0.01  # [m] a surface point within this of a contact counts as covered


@dataclass(frozen=True)
class Spacing:
    """How far apart kept grasps must be: ``translation`` [m] between tool
    centre points or ``rotation`` [rad] between orientations."""

    translation: float = DEFAULT_TRANSLATION
    rotation: float = DEFAULT_ROTATION

    def __post_init__(self) -> None:
        if not (np.isfinite(self.translation) and self.translation >= 0 and np.isfinite(self.rotation)
                and self.rotation >= 0):
            raise ValueError("Spacing needs finite translation >= 0 [m] and rotation >= 0 [rad]")


def tcp_points(grasps: Sequence[Grasp], tcp: np.ndarray) -> np.ndarray:
    """(n, 3) [m] each grasp's tool centre point, object frame."""
    poses = np.array([g.pose for g in grasps], float).reshape(-1, 4, 4)
    return poses[:, :3, :3] @ np.asarray(tcp, float) + poses[:, :3, 3]


def rotation_distance(a: np.ndarray, b: np.ndarray, approach: np.ndarray, symmetry: int = 1) -> float:
    """[rad] the angle between rotations ``a`` and ``b`` (3, 3), the smallest
    over the ``symmetry`` turns of ``b`` about its hand-frame ``approach`` axis."""
    turns = Rotation.from_rotvec(np.outer(2 * np.pi * np.arange(symmetry) / symmetry, approach))
    relative = Rotation.from_matrix(a.T @ b) * turns
    return float(np.min(relative.magnitude()))


def diverse(grasps: Iterable[Grasp], top: int, spacing: Spacing, tcp: np.ndarray, approach: np.ndarray,
            symmetry: int = 1) -> list[Grasp]:
    """The first ``top`` grasps of ``grasps`` (in their order: rank order)
    that are each at least ``spacing`` from every one kept before them (read
    lazily: a database cursor is read only as far as needed)."""
    kept: list[Grasp] = []
    centres: list[np.ndarray] = []
    for g in grasps:
        pose = np.asarray(g.pose, float)
        centre = pose[:3, :3] @ np.asarray(tcp, float) + pose[:3, 3]
        if all(np.linalg.norm(centre - c) >= spacing.translation
               or rotation_distance(np.asarray(k.pose, float)[:3, :3], pose[:3, :3], approach, symmetry)
               >= spacing.rotation for k, c in zip(kept, centres)):
            kept.append(g)
            centres.append(centre)
            if len(kept) == top:
                break
    return kept


def coverage(surface: np.ndarray, contacts: np.ndarray, radius: float = COVERAGE_RADIUS) -> float:
    """Fraction of ``surface`` points (n, 3) [m] (an even sample of the
    object's surface) within ``radius`` [m] of any contact (k, 3) [m]."""
    if len(surface) == 0:
        raise ValueError("coverage needs surface points")
    if len(contacts) == 0:
        return 0.0
    distance, _ = cKDTree(np.asarray(contacts, float)).query(np.asarray(surface, float), k=1)
    return float(np.mean(distance <= radius))
