"""Which joints close, which links are a finger, how much open travel a
grasp leaves: known answers on the Panda and the Barrett (no simulator)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from helpers import NUM_TOL, assert_close
from hypothesis import given
from hypothesis import strategies as st

from planner.record.contacts import HandContacts
from planner.specs.hands import load_hand
from planner.validation import fingers as fg
from tests.validation.support import as_row_of


def panda_grasp(q: float, links: tuple[str, ...] = ("panda_leftfinger", "panda_rightfinger")):  # type: ignore[no-untyped-def]
    contacts = HandContacts(np.array([[0.0, q, 0.0], [0.0, -q, 0.0]])[:len(links)],
                            np.array([[0.0, -1.0, 0.0], [0.0, 1.0, 0.0]])[:len(links)], links)
    return as_row_of("panda", np.eye(4), {"panda_finger_joint1": q, "panda_finger_joint2": q}, contacts)


def test_mimics_close_at_their_masters_rate_and_preshapes_override_the_synergy() -> None:
    panda, barrett = load_hand("panda"), load_hand("barrett")
    assert fg.closing_rates(panda, "wide") == {"panda_finger_joint1": -1.0, "panda_finger_joint2": -1.0}
    pinch = fg.closing_rates(barrett, "pinch")  # finger 3 stays out, the spread holds
    assert pinch["bh_j12_joint"] == 1.0 and pinch["bh_j13_joint"] == pytest.approx(0.3333)
    assert pinch["bh_j32_joint"] == pinch["bh_j33_joint"] == pinch["bh_j11_joint"] == pinch["bh_j21_joint"] == 0.0


def test_fingers_are_counted_as_fingers_not_links() -> None:
    panda, barrett = load_hand("panda"), load_hand("barrett")
    assert fg.fingers(panda, fg.closing_rates(panda, "wide")) == (
        frozenset({"panda_leftfinger"}), frozenset({"panda_rightfinger"}))
    wrap = fg.fingers(barrett, fg.closing_rates(barrett, "wrap"))
    assert wrap == tuple(frozenset({f"bh_finger_{k}2_link", f"bh_finger_{k}3_link"}) for k in (1, 2, 3))
    assert len(fg.fingers(barrett, fg.closing_rates(barrett, "pinch"))) == 2


#: [m] joint frames the simulator gives for the hand placed at a grasp pose and at
#: the origin agree to about 1e-7 m (measured 7e-8 on a Barrett grasp's open travel).
FRAME_TOL = 1e-6
#: The Panda's finger axes (hand frame): the left finger opens along +y, the right along -y.
PANDA_AXES = {"panda_finger_joint1": (np.zeros(3), np.array([0.0, 1.0, 0.0])),
              "panda_finger_joint2": (np.zeros(3), np.array([0.0, -1.0, 0.0]))}


@given(q=st.floats(0.0, 0.04))
def test_a_prismatic_finger_has_its_distance_to_the_open_limit_left(q: float) -> None:
    panda = load_hand("panda")
    assert fg.clearance(panda, panda_grasp(q), PANDA_AXES) == pytest.approx(0.04 - q)


def test_only_touching_fingers_count() -> None:
    panda = load_hand("panda")
    untouched = replace(panda_grasp(0.04), contacts=HandContacts(np.zeros((0, 3)), np.zeros((0, 3)), ()))
    assert fg.clearance(panda, untouched, PANDA_AXES) == np.inf


def test_a_coupled_finger_has_its_contacts_travel_back_along_the_synergy_left() -> None:
    # Barrett finger 3 flexed 0.1 rad (its distal joint 0.1 / 3, coupled): a fingertip contact 8 cm from
    # the proximal axis and 3 cm past the distal axis moves 0.08 + 0.03 / 3 m per radian of closing, so
    # opening the finger to its limit takes it 0.1 x 0.09 m back (not the distal joint's own 0.1 / 3 x 0.03)
    barrett = load_hand("barrett")
    x = np.array([1.0, 0.0, 0.0])
    axes = {"bh_j32_joint": (np.array([0.0, 0.05, 0.0754]), x), "bh_j33_joint": (np.array([0.0, 0.05, 0.1254]), x)}
    contacts = HandContacts(np.array([[0.0, 0.05, 0.0754 + 0.08]]), np.array([[0.0, 0.0, 1.0]]),
                            ("bh_finger_33_link",))
    grasp = as_row_of("barrett", np.eye(4), {"bh_j32_joint": 0.1, "bh_j33_joint": 0.1 * 0.3333}, contacts, "wrap")
    assert fg.levers(barrett, grasp, axes) == pytest.approx({"bh_j32_joint": 0.08, "bh_j33_joint": 0.03})
    assert fg.clearance(barrett, grasp, axes) == pytest.approx(0.1 * (0.08 + 0.03 * 0.3333))
    # broken away (the distal joint closed on to 0.1 rad alone): its own travel back, 0.1 x 0.03 m
    broken = as_row_of("barrett", np.eye(4), {"bh_j32_joint": 0.1, "bh_j33_joint": 0.1}, contacts, "wrap")
    assert fg.clearance(barrett, broken, axes) == pytest.approx(0.1 * 0.03)


def test_the_trials_clearance_is_the_sweeps_open_margin() -> None:
    """One formula: the shake trial's open travel of a planned Barrett grasp
    (its joint axes from the simulator, hand frame) is the open margin the
    sweep stored (its joint frames from closing, object frame)."""
    from planner.geometry.solid import load_object
    from planner.plan.closing import Closed, Grasper
    from planner.plan.measures import measure
    from planner.sim import Sim
    from planner.specs.preshapes import load_preshapes
    from planner.validation.actuation import joint_axes

    barrett, obj = load_hand("barrett"), load_object("cylinder")
    wrap = {p.name: p for p in load_preshapes(barrett)}["wrap"]
    with Sim() as sim:
        closed = Grasper.for_mesh(sim, barrett, obj.mesh).close(np.zeros(3), np.array([0.0, 0.0, -1.0]), 0.3, 0.01,
                                                                  wrap, obj.torque_scale)
        assert isinstance(closed, Closed)
        margin = measure(closed.contacts, closed.frames, barrett, wrap, closed.closed_joints, obj).open_margin  # type: ignore[arg-type]
        body = sim.load_urdf(barrett.urdf)  # at the origin: the hand frame
        sim.set_joints(body, closed.closed_joints)
        axes = joint_axes(sim, barrett, body)
    grasp = as_row_of("barrett", closed.pose, closed.closed_joints, closed.contacts, "wrap")
    assert np.isfinite(margin) and margin > 0
    assert_close(fg.clearance(barrett, grasp, axes), margin, FRAME_TOL)


def test_levers_are_measured_in_the_hand_frame() -> None:
    # the same contact, the grasp pose moved: the lever is unchanged
    barrett = load_hand("barrett")
    axis = (np.array([0.0, 0.0, 0.1]), np.array([0.0, 1.0, 0.0]))
    pose = np.eye(4)
    pose[:3, 3] = [0.3, -0.2, 0.5]
    contacts = HandContacts(np.array([[0.03, 0.0, 0.14]]) + pose[:3, 3], np.array([[1.0, 0, 0]]),
                            ("bh_finger_13_link",))
    grasp = as_row_of("barrett", pose, {}, contacts)
    assert_close(fg.levers(barrett, grasp, {"bh_j12_joint": axis})["bh_j12_joint"], 0.05, NUM_TOL)


def test_the_start_is_a_gap_short_of_the_grasp_with_mimics_in_step() -> None:
    panda, barrett = load_hand("panda"), load_hand("barrett")
    start = fg.start_joints(panda, panda_grasp(0.02), fg.closing_rates(panda, "wide"), {}, 0.005)
    assert start == pytest.approx({"panda_finger_joint1": 0.025, "panda_finger_joint2": 0.025})
    assert fg.start_joints(panda, panda_grasp(0.038), fg.closing_rates(panda, "wide"), {}, 0.005) == pytest.approx(
        {"panda_finger_joint1": 0.04, "panda_finger_joint2": 0.04})  # never past the open limit
    grasp = as_row_of("barrett", np.eye(4), {"bh_j11_joint": 0.5, "bh_j32_joint": 1.0, "bh_j33_joint": 1 / 3},
                      HandContacts(np.zeros((0, 3)), np.zeros((0, 3)), ()))
    start = fg.start_joints(barrett, grasp, fg.closing_rates(barrett, "wrap"), {"bh_j32_joint": 0.1}, 0.005)
    assert start["bh_j32_joint"] == pytest.approx(0.95) and start["bh_j33_joint"] == pytest.approx(0.95 * 0.3333)
    assert start["bh_j11_joint"] == start["bh_j21_joint"] == 0.5  # the spread holds


def _levers_joint_by_joint(hand, grasp, axes):  # type: ignore[no-untyped-def]
    """The levers as they were worked out before, one joint at a time (the reference)."""
    from planner.geometry.frames import rows_cross

    to_hand = np.linalg.inv(np.asarray(grasp.pose, float))
    points = grasp.contacts.points @ to_hand[:3, :3].T + to_hand[:3, 3]
    links = np.array(grasp.contacts.links, dtype=object)
    out = {}
    for j in hand.joints:
        if j.kind != "revolute" or j.name not in axes or not len(points):
            continue
        on = points[np.isin(links, j.moves)]
        if len(on):
            origin, axis = axes[j.name]
            out[j.name] = float(np.max(np.linalg.norm(rows_cross(on - origin, np.broadcast_to(axis, on.shape)),
                                                      axis=1)))
    return out


@given(st.integers(0, 2**32 - 1), st.integers(0, 12), st.sampled_from(["barrett", "allegro", "panda"]))
def test_levers_of_every_joint_at_once_are_those_joint_by_joint_to_the_bit(seed, n, name) -> None:  # type: ignore[no-untyped-def]
    hand = load_hand(name)
    rng = np.random.default_rng(seed)
    names = [link for j in hand.joints for link in j.moves] + ["palm_or_other"]
    links = tuple(names[i] for i in rng.integers(0, len(names), n))
    contacts = HandContacts(rng.normal(0.0, 0.1, (n, 3)), rng.normal(size=(n, 3)), links)
    pose = np.eye(4)
    pose[:3, :3] = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    pose[:3, 3] = rng.normal(0.0, 0.2, 3)
    axes = {j.name: (rng.normal(0.0, 0.1, 3), rng.normal(size=3)) for j in hand.joints if rng.random() < 0.8}
    grasp = as_row_of(name, pose, {}, contacts)
    got, want = fg.levers(hand, grasp, axes), _levers_joint_by_joint(hand, grasp, axes)
    assert list(got) == list(want) and all(repr(got[k]) == repr(want[k]) for k in want)
