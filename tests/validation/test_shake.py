"""The shake trial against known physical answers.

A 0.2 kg box pinched across its centre by the Panda (one 70 N motor: 35 N
per pad) slips when 2 mu 35 N < m g, i.e. below mu* = 0.028; the same grasp
backed off 6 cm touches nothing; a grasp at the gripper's opening is
flagged; pads pressing a sphere above its equator push it out when the
wedge is steeper than the friction cone. Plus trials batched in one world.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from planner.geometry.solid import prepare
from planner.specs.hands import load_hand
from planner.specs.objects import ObjectSpec
from planner.validation.shake import ShakeSettings, recorded, trial, trials
from planner.validation.tolerances import GRAVITY
from tests.validation.support import backed_off, box, box_of, pinch

#: The pinched box and the Panda's pad force: the friction below which it slips.
MASS, PAD_FORCE = 0.2, 35.0
MU_STAR = MASS * GRAVITY / (2 * PAD_FORCE)


@pytest.fixture(scope="module")
def pinched():  # type: ignore[no-untyped-def]
    hand = load_hand("panda")
    obj = box(0.04)
    return hand, obj, pinch(hand, obj)


@pytest.mark.parametrize("mu, held", [(0.5, True), (1.4 * MU_STAR, True), (0.02, False)])
def test_a_box_pinched_across_its_centre_holds_above_the_friction_its_weight_needs(pinched, mu, held) -> None:  # type: ignore[no-untyped-def]
    hand, obj, grasp = pinched
    result = trial(hand, obj, grasp, friction=mu)
    assert result.success is held and result.reason == ("held" if held else "slipped")
    assert result.fingers_in_contact == 2  # fingers, not links: each Panda finger is one link here
    if held:
        assert result.shaking_linear < 0.003 and result.closing_linear < 0.001
    else:
        assert result.shaking_linear >= 0.01 or result.shaking_angular >= 0.25


@pytest.mark.parametrize("share, held", [(0.8, True), (1.25, False)])
def test_the_pinched_box_holds_up_to_the_weight_its_pads_friction_carries(pinched, share, held) -> None:  # type: ignore[no-untyped-def]
    # at mu 0.5 the two pads carry 2 x 0.5 x 35 N = 35 N: 3.57 kg
    hand, obj, grasp = pinched
    result = trial(hand, obj, grasp, mass=share * 2 * 0.5 * PAD_FORCE / GRAVITY)
    assert result.reason == ("held" if held else "slipped")


def test_the_same_grasp_backed_off_6_cm_touches_nothing(pinched) -> None:  # type: ignore[no-untyped-def]
    hand, obj, grasp = pinched
    result = trial(hand, obj, backed_off(grasp, hand, 0.06))
    assert not result.success and result.reason == "no_contact" and result.fingers_in_contact == 0


def test_a_grasp_at_zero_clearance_is_flagged_not_simulated() -> None:
    # 7.9 cm across at the Panda's 8 cm opening: the planner closes with both fingers at their open
    # limit; the open hand could not have been put around the box (no squeeze travel)
    hand = load_hand("panda")
    wide, roomy = box(0.079), box(0.074)
    flagged = trial(hand, wide, pinch(hand, wide))
    assert flagged.reason == "no_clearance" and not flagged.success
    assert trial(hand, roomy, pinch(hand, roomy)).reason == "held"  # 3 mm of travel left: simulated


def test_the_pads_torsional_friction_holds_an_off_centre_pinch() -> None:
    # 1.2 kg box pinched 2 cm off its centre of mass: loads along the approach turn it about the line
    # between the pads with 0.24 N m; Bullet's contact points on the flat face resist ~0.1-0.15 N m by
    # themselves, the pads' torsional friction (2 mu torsion_radius F = 0.15 N m) the rest
    hand = load_hand("panda")
    obj = box_of((0.12, 0.04, 0.06), 1.2)
    grasp = pinch(hand, obj, offset=(0.02, 0.0, 0.0))
    point_pads = replace(hand, contacts={k: replace(m, torsion_radius=0.0) for k, m in hand.contacts.items()})
    assert trial(hand, obj, grasp).reason == "held"
    assert trial(point_pads, obj, grasp).reason == "slipped"


@pytest.mark.parametrize("height, mu, reason", [(0.0, 0.6, "held"), (0.022, 0.6, "slipped"),
                                                (0.022, 0.4, "squeezed_out")])
def test_a_sphere_held_by_the_pads_rims_swings_and_is_squeezed_out_when_the_wedge_beats_friction(
        height, mu, reason) -> None:  # type: ignore[no-untyped-def]
    # the flat pads (17.5 mm tall, centred on the tool centre point) 2.2 cm above the centre of a 3 cm
    # ball touch it with their lower rims, 13.25 mm above its equator: a wedge of angle asin(13.25 / 30),
    # tan = 0.49, which squeezing pushes out of the fingers unless mu > tan; held, it hangs from two rim
    # points and swings about the line between them (a rim has no contact patch, no torsional friction),
    # while pads pressed on the equator hold it
    hand = load_hand("panda")
    ball = prepare(ObjectSpec(name="ball", kind="sphere", dims=(0.03,), mass=0.2))
    # contacts read as PyBullet's points, which lie on the rim: read as patches they spread up to ~2 mm
    # off it (the patch depth), outside the rim band, and the trial keeps the pad's torsion (known gap)
    result = trial(hand, ball, pinch(hand, ball, offset=(0.0, 0.0, height), contacts="points"), friction=mu)
    assert result.reason == reason
    if reason == "squeezed_out":
        assert result.fingers_in_contact == 0 and result.closing_linear >= 0.01
    if reason == "slipped":
        assert result.fingers_in_contact == 2 and result.shaking_angular >= 0.25


def test_a_hand_starting_deep_in_the_object_is_flagged(pinched) -> None:  # type: ignore[no-untyped-def]
    hand, obj, grasp = pinched
    result = trial(hand, obj, backed_off(grasp, hand, -0.03))  # the palm 3 cm further down: inside the box
    assert result.reason == "start_overlap" and not result.success


def test_trials_are_repeatable_and_batches_give_the_same_results(pinched) -> None:  # type: ignore[no-untyped-def]
    hand, obj, grasp = pinched
    grasps = [grasp, backed_off(grasp, hand, 0.06), backed_off(grasp, hand, -0.03), backed_off(grasp, hand, 0.002)]
    alone = [trial(hand, obj, g, friction=0.3) for g in grasps]
    assert [t.reason for t in alone] == ["held", "no_contact", "start_overlap", "held"]
    assert trials(hand, obj, grasps, friction=0.3) == alone  # one world per trial: bit for bit
    # one world for all: a single-part object gives the very same numbers (several parts: same verdicts)
    assert trials(hand, obj, grasps, ShakeSettings(batch=4), friction=0.3) == alone
    slippery = trials(hand, obj, [grasp, grasps[1]], ShakeSettings(batch=2), friction=0.02)
    assert [t.reason for t in slippery] == ["slipped", "no_contact"]


def test_a_batch_beyond_the_collision_filter_bits_is_refused() -> None:
    from planner.errors import ConfigError

    with pytest.raises(ConfigError, match="batch must be 1..30"):
        ShakeSettings(batch=31)


def test_settings_round_trip_through_json() -> None:
    import json

    s = ShakeSettings(batch=3, load=1.5)
    assert ShakeSettings(**json.loads(s.to_json())) == s
    assert np.isclose(ShakeSettings().dt, 1 / 480)


def test_each_result_records_the_hands_actuators_breakaway_joints_and_torsion_radii() -> None:
    import json

    stored = json.loads(recorded(ShakeSettings(), load_hand("barrett")))
    assert stored["actuators"] == {"effort": 1.7, "closing_speed": 2.4, "backdrivable": False,
                                   "source": stored["actuators"]["source"]}
    assert stored["breakaway"] == ["bh_j12_joint", "bh_j22_joint", "bh_j32_joint"]
    assert stored["torsion_radius"] == {f"bh_finger_{i}3_link": 0.0025 for i in (1, 2, 3)}
    assert stored["dt"] == ShakeSettings().dt and stored["hand"] == "barrett"


def test_the_settled_contacts_of_a_centred_pinch_are_on_both_faces_pressing_inwards(pinched) -> None:  # type: ignore[no-untyped-def]
    hand, obj, grasp = pinched
    seen = []
    result = trials(hand, obj, [grasp], on_settled=lambda g, c: seen.append((g, c)))[0]
    assert result.success
    [(g, contacts)] = seen
    assert g is grasp and len(contacts) >= 2 and set(contacts.links) <= set(hand.contact_links)
    # the pads squeeze along one axis of the box: points on two opposite faces, normals into the box
    axis = int(np.argmax(np.abs(contacts.normals).sum(axis=0)))
    half = np.max(np.abs(obj.mesh.vertices[:, axis]))
    np.testing.assert_allclose(np.abs(contacts.points[:, axis]), half, atol=1e-3)
    inward = -np.sign(contacts.points[:, axis]) * contacts.normals[:, axis]
    assert (inward > 0.99).all()
    assert set(np.sign(contacts.points[:, axis])) == {-1.0, 1.0}


def test_a_grasp_backed_off_settles_into_no_contacts(pinched) -> None:  # type: ignore[no-untyped-def]
    hand, obj, grasp = pinched
    seen = []
    trials(hand, obj, [backed_off(grasp, hand, 0.06)], on_settled=lambda g, c: seen.append(c))
    assert [len(c) for c in seen] == [0]


def test_a_world_holds_as_many_trials_as_the_settings_allow() -> None:
    from planner.sim.dynamics import FILTER_BITS
    from planner.validation.settings import MAX_BATCH

    assert MAX_BATCH == FILTER_BITS
