"""A grasp's width: the gap between the pads of a hand that declares them
(the PR2's: signed, known at its limits, PyBullet's wherever the hand is),
the Panda's opening bit for bit, no width for the other hands."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from planner.plan.sweep import SweepSettings
from planner.plan.unit import UnitSpec, run_unit
from planner.plan.width import closed_width, pad_gap
from planner.sim import Sim, pb
from planner.specs.hands import load_hand

#: [m] fcl's signed distance between the PR2's box pads against the known answer (libccd's EPA tolerance).
EPA_TOL = 2e-6
#: [m] PyBullet's closest points of the pads, less its margins (hand.distance_offset), against fcl's exact
#: shapes: PyBullet holds them in float32 (measured within 1.3 um).
PYBULLET_TOL = 1e-5
#: [m] the PR2's pads fully open (0.548 rad each), as fcl and PyBullet both measure it.
PR2_OPEN = 0.088323


def pr2(left: float, right: float) -> dict[str, float]:
    return {"left_gripper_joint": left, "right_gripper_joint": right}


def test_the_pr2s_width_is_the_signed_gap_between_its_pads() -> None:
    """At 0 the two 10 mm thick pad boxes lie one in the other (the URDF's quirk): -10 mm (a roll of -3.1415
    rad, not pi, tilts the right one ~1 um deeper); fully open 88 mm; wider as either finger opens."""
    hand = load_hand("pr2")
    assert closed_width(hand, pr2(0.0, 0.0)) == pytest.approx(-0.010, abs=EPA_TOL)
    assert closed_width(hand, pr2(0.548, 0.548)) == pytest.approx(PR2_OPEN, abs=EPA_TOL)
    steps = np.linspace(0.0, 0.548, 12)
    assert np.all(np.diff([pad_gap(hand, pr2(q, 0.2)) for q in steps]) > 0)
    assert np.all(np.diff([pad_gap(hand, pr2(0.2, q)) for q in steps]) > 0)


def test_the_pr2s_width_is_pybullets_gap_wherever_the_hand_is() -> None:
    """The width is read in the hand's own frame: PyBullet's closest points between the pads of the hand at
    random poses and joints, less its margins, are the same numbers (overlapping ones too)."""
    hand = load_hand("pr2")
    rng = np.random.default_rng(3)
    gaps = []
    with Sim() as sim:
        body = sim.load_urdf(hand.urdf)
        a, b = (body.links[name] for name in hand.width_links or ())
        for k in range(20):
            joints = pr2(*rng.uniform(0.0, 0.548 if k % 2 else 0.05, 2))  # half of them nearly closed
            pose = np.eye(4)
            pose[:3, :3] = Rotation.random(random_state=k).as_matrix()
            pose[:3, 3] = rng.uniform(-1.0, 1.0, 3)
            sim.set_pose(body, pose)
            sim.set_joints(body, joints)
            rows = pb.getClosestPoints(body.uid, body.uid, 1.0, linkIndexA=a, linkIndexB=b,
                                       physicsClientId=sim.client)
            reported = min(r[8] for r in rows) + hand.distance_offset
            assert closed_width(hand, joints) == pytest.approx(reported, abs=PYBULLET_TOL), k
            gaps.append(reported)
    assert min(gaps) < 0 < max(gaps)


def test_the_pandas_width_is_its_opening_and_the_other_hands_have_none() -> None:
    panda = load_hand("panda")
    for q in np.random.default_rng(0).uniform(0.0, 0.04, 5):
        joints = {"panda_finger_joint1": q, "panda_finger_joint2": q}
        assert closed_width(panda, joints) == panda.opening(joints)  # bit for bit
    assert closed_width(panda, {"panda_finger_joint1": 0.01, "panda_finger_joint2": 0.01}) == 0.02
    assert closed_width(load_hand("barrett"), {}) is None
    assert closed_width(load_hand("allegro"), {}) is None
    with pytest.raises(ValueError, match="declares no width_links"):
        pad_gap(panda, {})


def test_a_pr2_sweep_stores_the_width_of_its_closed_joints() -> None:
    r = run_unit(UnitSpec("box", "pr2", SweepSettings(approaches=4, rolls=2, preshapes=("wide",),
                                                      reach_placements=0), seed=1))
    assert r.error is None and r.grasps
    for g in r.grasps:
        assert g.width == closed_width(load_hand("pr2"), g.closed_joints)
        assert -0.010 - EPA_TOL <= g.width <= PR2_OPEN + EPA_TOL  # type: ignore[operator]
