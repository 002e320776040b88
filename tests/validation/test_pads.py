"""Where a pad touches: its face (a contact patch, torsional friction) or its
rim (an edge or corner: none)."""

from __future__ import annotations

import numpy as np
import pytest

from planner.specs.hands import load_hand
from planner.validation.pads import has_patch, link_planes, on_edge


@pytest.fixture(scope="module")
def finger() -> tuple[np.ndarray, ...]:
    return link_planes(load_hand("panda").urdf, "panda_leftfinger")


# the left Panda finger's pad: the face y ~ 0 of its link frame (outward normal -y, towards the object;
# contacts are reported 1.1 mm out), x within +-8.7 mm, z from ~36 to ~54 mm; the object's inward normal
# at a contact on it is -y
FACE = np.array([0.0, -1.0, 0.0])
TILTED = np.array([0.0, -np.cos(np.radians(26)), np.sin(np.radians(26))])  # a ball 13 mm above its equator


def test_the_finger_hull_has_a_flat_pad_face(finger) -> None:  # type: ignore[no-untyped-def]
    assert len(finger) == 1 and (finger[0][:, :3] @ FACE > 0.99).any()  # facets within a few degrees


@pytest.mark.parametrize("point, normal, edge", [
    ((0.0, -1.1, 45.0), FACE, False),  # the middle of the pad
    ((0.0, -1.1, 45.0), TILTED, False),  # a ball on the middle of the pad: a (curved) patch
    ((-0.3, -1.0, 53.8), TILTED, True),  # the pad's upper rim on a ball off its equator
    ((8.7, -1.1, 50.2), FACE, False),  # a box face flat on the pad, reported at its side rim
    ((8.7, -1.1, 53.8), TILTED, True),  # a corner
])
def test_a_contact_on_the_pad_rim_is_an_edge_unless_the_object_lies_flat_on_the_pad(  # type: ignore[no-untyped-def]
        finger, point, normal, edge) -> None:
    assert on_edge(finger, np.array(point) / 1000, normal) is edge


def test_one_contact_on_the_face_makes_a_patch(finger) -> None:  # type: ignore[no-untyped-def]
    rim = np.array([[-0.3, -1.0, 53.8], [3.0, -1.0, 53.8]]) / 1000
    assert not has_patch(finger, rim, np.array([TILTED, TILTED]))
    assert has_patch(finger, np.vstack([rim, [[0.0, -1.1e-3, 0.045]]]), np.array([TILTED, TILTED, FACE]))
