"""The hand as a trial drives it: forces and couplings from its specs,
fingers that a load cannot open."""

from __future__ import annotations

import pytest

from planner.sim import Sim, pb
from planner.sim.dynamics import Dynamics
from planner.specs.hands import load_hand
from planner.validation.actuation import drive_fingers, hold_closed
from planner.validation.shake import ShakeSettings


@pytest.fixture()
def barrett_on_a_plate():  # type: ignore[no-untyped-def]
    """Finger 3 of the Barrett closing on a fixed plate 15 cm above the wrist (7 cm above the palm)."""
    hand = load_hand("barrett")
    rates = {j.name: 0.0 for j in hand.joints} | {"bh_j32_joint": 1.0, "bh_j33_joint": 1 / 3}
    with Sim() as sim:
        dyn = Dynamics(sim)
        body = dyn.add_hand(hand.urdf)
        plate = pb.createMultiBody(0, pb.createCollisionShape(pb.GEOM_BOX, halfExtents=[0.2, 0.2, 0.01],
                                                              physicsClientId=sim.client),
                                   basePosition=[0, 0, 0.16], physicsClientId=sim.client)
        drive_fingers(dyn, hand, body, rates, {}, ShakeSettings().gear_erp)
        dyn.step(240)
        yield hand, dyn, body, plate, rates


def test_the_barrett_fingertip_pushes_with_its_published_force(barrett_on_a_plate) -> None:  # type: ignore[no-untyped-def]
    hand, dyn, body, plate, _ = barrett_on_a_plate
    rows = pb.getContactPoints(body.uid, plate, physicsClientId=dyn.c)
    assert {r[3] for r in rows} == {body.links["bh_finger_33_link"]}
    assert 15.0 < sum(r[9] for r in rows) < 23.0  # BH8-28x: ~20 N stalled at the fingertip
    q = dyn.joint_position(body, "bh_j32_joint"), dyn.joint_position(body, "bh_j33_joint")
    assert q[1] == pytest.approx(q[0] / 3, abs=0.005)  # the distal follows a third of the proximal


@pytest.mark.parametrize("backdrivable", [False, True])
def test_a_worm_geared_finger_cannot_be_pushed_open(barrett_on_a_plate, backdrivable: bool) -> None:  # type: ignore[no-untyped-def]
    hand, dyn, body, _, rates = barrett_on_a_plate
    assert hand.dynamics.backdrivable is False  # BH8-28x: non-backdrivable finger joints
    closed = dyn.joint_position(body, "bh_j32_joint")
    if not backdrivable:
        hold_closed(dyn, hand, body, rates)
    # a load opening the finger with ten times what its motor can push
    dyn.velocity_motor(body, "bh_j32_joint", -2.0, 10 * hand.dynamics.effort)
    dyn.step(120)
    opened = closed - dyn.joint_position(body, "bh_j32_joint")
    assert (opened > 0.1) if backdrivable else opened < 1e-3
