"""Resting poses on a table (:mod:`planner.geometry.stable`)."""

from __future__ import annotations

import numpy as np

from planner.geometry.solid import load_object
from planner.geometry.stable import resting_poses


def test_resting_poses_lie_on_the_table_with_the_centre_of_mass_above_the_origin() -> None:
    obj = load_object("mug")
    poses = resting_poses(obj.mesh, obj.com, limit=4)
    assert len(poses) == 4
    probabilities = [p.probability for p in poses]
    assert probabilities == sorted(probabilities, reverse=True) and 0 < sum(probabilities) <= 1 + 1e-9
    for p in poses:
        placed = obj.mesh.vertices @ p.pose[:3, :3].T + p.pose[:3, 3]
        assert abs(placed[:, 2].min()) < 1e-6, "resting on z = 0"
        com = p.pose[:3, :3] @ obj.com + p.pose[:3, 3]
        assert np.allclose(com[:2], 0.0, atol=1e-6) and com[2] > 0
        moved = p.placed(0.5, -0.1, 0.7)
        assert np.allclose(moved[:3, 3] - p.pose[:3, 3], [0.5, -0.1, 0.7])


def test_a_box_rests_on_its_largest_faces_first() -> None:
    obj = load_object("box")
    first = resting_poses(obj.mesh, obj.com, limit=1)[0]
    up = first.pose[:3, :3].T @ np.array([0.0, 0.0, 1.0])  # the world's up in the box frame
    axis = int(np.argmax(np.abs(up)))
    assert np.isclose(abs(up[axis]), 1.0, atol=1e-6)
    assert axis == int(np.argmin(obj.mesh.extents)), "it lies flat: its shortest side points up"
