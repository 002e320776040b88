"""The hand as a trial drives it: forces and couplings from its specs,
fingers that a load cannot open."""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import replace

import pytest

from planner.sim import Sim, pb
from planner.sim.dynamics import Dynamics
from planner.specs.hands import HandSpec, load_hand
from planner.validation.actuation import break_away, drive_fingers, hold_closed
from planner.validation.shake import ShakeSettings

#: Barrett finger 3 closing alone: the proximal joint at the synergy rate, its distal mimic a third of it.
FINGER_3 = {"bh_j32_joint": 1.0, "bh_j33_joint": 1 / 3}


@contextmanager
def finger_3_against(hand: HandSpec, half_extents: list[float], position: list[float]):  # type: ignore[no-untyped-def]
    """(dynamics, hand body, a fixed box of ``half_extents`` at ``position``, rates, clutches), finger 3 driven."""
    rates = {j.name: 0.0 for j in hand.joints} | FINGER_3
    with Sim() as sim:
        dyn = Dynamics(sim)
        body = dyn.add_hand(hand.urdf)
        box = pb.createMultiBody(0, pb.createCollisionShape(pb.GEOM_BOX, halfExtents=half_extents,
                                                            physicsClientId=sim.client),
                                 basePosition=position, physicsClientId=sim.client)
        yield dyn, body, box, rates, drive_fingers(dyn, hand, body, rates, {}, ShakeSettings().gear_erp)


@pytest.fixture()
def barrett_on_a_plate():  # type: ignore[no-untyped-def]
    """Finger 3 of the Barrett closing on a fixed plate 15 cm above the wrist (7 cm above the palm)."""
    hand = load_hand("barrett")
    with finger_3_against(hand, [0.2, 0.2, 0.01], [0, 0, 0.16]) as (dyn, body, plate, rates, _):
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
    assert hand.actuators.backdrivable is False  # BH8-28x: non-backdrivable finger joints
    closed = dyn.joint_position(body, "bh_j32_joint")
    if not backdrivable:
        hold_closed(dyn, hand, body, rates)
    # a load opening the finger with ten times what its motor can push
    dyn.velocity_motor(body, "bh_j32_joint", -2.0, 10 * hand.actuators.effort)
    dyn.step(120)
    opened = closed - dyn.joint_position(body, "bh_j32_joint")
    assert (opened > 0.1) if backdrivable else opened < 1e-3


@pytest.mark.parametrize("breakaway", [True, False])
def test_a_barrett_finger_stopped_at_its_proximal_link_curls_on_with_its_distal(breakaway: bool) -> None:
    # a bar across finger 3's proximal link only (the distal link is beyond it): the BH8's TorqueSwitch
    # lets the distal joint close on alone once the proximal link is stopped, a rigid 1:3 gear does not
    hand = load_hand("barrett")
    if not breakaway:
        hand = replace(hand, joints=tuple(replace(j, breakaway=False) for j in hand.joints))
    with finger_3_against(hand, [0.03, 0.01, 0.005], [0, 0.08, 0.11]) as (dyn, body, bar, _, clutches):
        assert [c.driven for c in clutches] == (["bh_j32_joint"] if breakaway else [])
        for _ in range(480):  # 1 s: the distal closes at a third of the proximal's 2.4 rad/s
            dyn.step()
            break_away(dyn, hand, body, clutches, dyn.touching_links(body, bar))
        proximal, distal = dyn.joint_position(body, "bh_j32_joint"), dyn.joint_position(body, "bh_j33_joint")
        touching = dyn.touching_links(body, bar)
    assert body.links["bh_finger_32_link"] in touching
    assert 0.2 < proximal < 1.0  # stopped by the bar
    if breakaway:
        assert not clutches and distal > proximal / 3 + 0.3  # curled on past the 1:3 coupling
    else:
        assert distal == pytest.approx(proximal / 3, abs=0.02)  # the gear (erp 0.8) gives ~0.01 rad
