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


@given(q=st.floats(0.0, 0.04))
def test_a_prismatic_finger_has_its_distance_to_the_open_limit_left(q: float) -> None:
    panda = load_hand("panda")
    assert fg.clearance(panda, panda_grasp(q), fg.closing_rates(panda, "wide"), {}) == pytest.approx(0.04 - q)


def test_only_touching_fingers_count() -> None:
    panda = load_hand("panda")
    rates = fg.closing_rates(panda, "wide")
    untouched = replace(panda_grasp(0.04), contacts=HandContacts(np.zeros((0, 3)), np.zeros((0, 3)), ()))
    assert fg.clearance(panda, untouched, rates, {}) == np.inf


def test_a_revolute_finger_has_its_angle_times_its_lever_left() -> None:
    # Barrett finger 3 flexed 0.1 rad, touching 8 cm from its proximal axis: 8 mm of travel at the contact
    barrett = load_hand("barrett")
    axis = (np.array([0.0, 0.05, 0.0754]), np.array([1.0, 0.0, 0.0]))
    contacts = HandContacts(np.array([[0.0, 0.05, 0.0754 + 0.08]]), np.array([[0.0, 0.0, 1.0]]),
                            ("bh_finger_33_link",))
    grasp = as_row_of("barrett", np.eye(4), {"bh_j32_joint": 0.1, "bh_j33_joint": 0.1 / 3}, contacts)
    lever = fg.levers(barrett, grasp, {"bh_j32_joint": axis, "bh_j33_joint": axis})
    assert lever == pytest.approx({"bh_j32_joint": 0.08, "bh_j33_joint": 0.08})
    assert fg.clearance(barrett, grasp, fg.closing_rates(barrett, "wrap"), lever) == pytest.approx(0.1 / 3 * 0.08)


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
