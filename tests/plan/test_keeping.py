"""The keeper (:mod:`planner.plan.keeping`): a squeeze's end kept as a grasp of its own is one the hand can approach."""

import pytest

from planner.geometry.solid import load_object
from planner.plan import unit
from planner.plan.sweep import SweepSettings
from planner.plan.tolerances import FINGER_CLEARANCE
from planner.specs.hands import load_hand


@pytest.fixture(scope="module")
def mug_grasps() -> list:
    """The Panda's grasps of the mug (60 points, 2 approach directions, seed 3): squeezes' ends among them."""
    return unit.plan_object(load_object("mug"), "panda", SweepSettings(approaches=60, rolls=2, reach_placements=0),
                            3).grasps


def test_a_squeezes_end_opens_as_its_parent_does(mug_grasps: list) -> None:
    """An end's open joints are its parent's opening (width + FINGER_CLEARANCE a side, as the antipodal sampler opens
    the hand for its chord), not the squeeze's last re-opening 1 mm wider than the closing before: stored as the
    pre-grasp posture (MoveIt's, ACRONYM's joints_open, the trials' start, the pre-grasp reach and table checks),
    that left each pad about 1.5 mm from the wall to approach along."""
    hand = load_hand("panda")
    ends = [i for i, g in enumerate(mug_grasps) if g.squeezed_from_turn is not None]
    assert ends
    for i in ends:
        parent, end = mug_grasps[i - 1], mug_grasps[i]
        assert end.open_joints == parent.open_joints
        assert hand.opening(hand.full_configuration(end.open_joints)) - end.width >= FINGER_CLEARANCE


def test_a_parent_knows_its_squeezes_end_is_kept(mug_grasps: list) -> None:
    """The grasp planned before each kept end (its parent: the same candidate, not force closure, force closure once
    squeezed) says so (``end_kept``, planner.db.ranking.FIRST: the end stands for it in the rank, also in a query's
    grasps planned on the spot and never stored); no other grasp does."""
    parents = {i - 1 for i, g in enumerate(mug_grasps) if g.squeezed_from_turn is not None}
    assert parents and [i for i, g in enumerate(mug_grasps) if g.end_kept] == sorted(parents)
    for i in parents:
        parent, end = mug_grasps[i], mug_grasps[i + 1]
        assert parent.candidate == end.candidate and not parent.force_closure and parent.measures.squeezed_force_closure
