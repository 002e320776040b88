"""The keeper (:mod:`planner.plan.keeping`): a squeeze's end kept as a grasp of its own is one the hand can approach."""

from dataclasses import replace

import numpy as np
import pytest

from planner.geometry.solid import load_object
from planner.plan import keeping, unit
from planner.plan.sweep import SweepSettings
from planner.plan.tolerances import FINGER_CLEARANCE
from planner.record.first import first_of
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


def test_a_squeezes_end_is_the_closing_its_squeeze_ended_in(monkeypatch: pytest.MonkeyPatch) -> None:
    """An end's pose, closed joints and contacts are those of its squeeze's last closing (opened as its parent, above):
    the hand is not closed once more there from its parent's opening (until ALGORITHM_VERSION 26 a second closing per
    end, ~5% of the mug's unit, that ended within 0.14 mm of the squeeze's)."""
    squeezes = []
    real = keeping.squeezed

    def spy(*args):  # type: ignore[no-untyped-def]
        squeezes.append(real(*args))
        return squeezes[-1]

    monkeypatch.setattr(keeping, "squeezed", spy)
    grasps = unit.plan_object(load_object("mug"), "panda", SweepSettings(approaches=60, rolls=2, reach_placements=0),
                              3).grasps
    last = {s.end.pose.tobytes(): s.end for s in squeezes if s is not None and s.force_closure and s.end is not None}
    ends = [g for g in grasps if g.squeezed_from_turn is not None]
    assert ends and len(last) >= len(ends)
    for end in ends:
        closing = last.get(np.asarray(end.pose, float).tobytes())
        assert closing is not None, "an end's pose is not where its squeeze ended"
        assert end.closed_joints == closing.closed_joints
        np.testing.assert_array_equal(end.contacts.points, closing.contacts.points)
        np.testing.assert_array_equal(end.contacts.normals, closing.contacts.normals)


def test_a_parent_whose_end_is_kept_takes_no_reach_slot(mug_grasps: list) -> None:
    """The sweep's reach goes to the grasps that rank first (planner.plan.unit.add_reachability): a parent whose end
    is kept does not (its end ranks for it), so it is ordered by its planned epsilon, not its squeeze's; a grasp force
    closure only once squeezed whose end was not kept still ranks first by its squeeze's epsilon."""
    parents = [g for g in mug_grasps if g.end_kept]
    assert parents
    for g in parents:
        assert first_of([g]) == [False] and unit._first_epsilon(g, False) == g.epsilon
        alone = replace(g, end_kept=False)
        assert first_of([alone]) == [True] and unit._first_epsilon(alone, True) == g.measures.squeezed_epsilon
