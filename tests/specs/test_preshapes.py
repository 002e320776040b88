"""Preshape taxonomies: every hand's preshapes load within the joint limits."""

from __future__ import annotations

import pytest
from helpers import NUM_TOL

from planner.errors import UnknownNameError
from planner.specs.hands import hand_names, load_hand
from planner.specs.preshapes import load_preshapes

HANDS = hand_names()


@pytest.mark.parametrize("name", HANDS)
def test_preshapes_load_within_limits(name: str) -> None:
    hand = load_hand(name)
    shapes = load_preshapes(hand)
    assert shapes
    for shape in shapes:
        assert set(shape.joints) == {j.name for j in hand.joints}
        for joint in hand.joints:
            assert joint.lower - NUM_TOL <= shape.joints[joint.name] <= joint.upper + NUM_TOL
        assert shape.tags and shape.taxonomy


def test_preshapes_fill_in_mimics() -> None:
    shapes = load_preshapes(load_hand("panda"))
    assert [s.name for s in shapes] == ["wide", "half"]
    assert shapes[0].joints["panda_finger_joint2"] == shapes[0].joints["panda_finger_joint1"] == 0.04
    with pytest.raises(UnknownNameError, match="Available preshapes: half, wide"):
        load_preshapes(load_hand("panda"), ["fist"])
