"""The Allegro's dynamic model as the real hand is: each joint closes at the velocity limit of Wonik's own
description of the hand, 7 rad/s (the trials and the settle closed at the default 0.5 rad/s until 2026-12-06, and
its URDF said 6 rad/s from no source), with the manufacturer's 0.7 N m; so a pinch closes in a few tenths of a
second of simulated time, not seconds; verdicts made with the slower hand are tried again."""

from __future__ import annotations

from dataclasses import replace

import mujoco
import numpy as np
import pytest

from planner.specs.hands import load_hand
from planner.specs.urdf import load_model
from planner.validation import mujoco_trial, shake
from planner.validation.mujoco_settings import MujocoSettings
from planner.validation.settings import ShakeSettings
from tests.validation.support import allegro_pinch

#: [rad/s] every joint's velocity limit in Wonik's description (simlabrobotics/allegro_hand_ros_v4,
#: allegro_hand_description: velocity="7"; Drake's model of the hand keeps it).
JOINT_SPEED = 7.0
#: [N m] every joint's torque, the manufacturer's (as Drake's allegro_hand_description states it).
JOINT_TORQUE = 0.7
#: [s] of simulated closing (the trial's steps before gravity comes on) the pinch may take: its thumb travels
#: 0.73 rad to the box and its index 1.3 rad to its stop, 0.19 s at 7 rad/s plus the stall and the settle (0.30 s
#: in all; 2.39 s at 0.5 rad/s).
PINCH_CLOSING = 0.5


def test_the_allegro_closes_at_its_joints_velocity_limit_with_their_torque() -> None:
    hand = load_hand("allegro")
    joints = load_model(hand.urdf).joint_map
    assert hand.actuators.closing_speed == JOINT_SPEED and hand.actuators.effort == JOINT_TORQUE
    assert {joints[j.name].limit.velocity for j in hand.joints} == {JOINT_SPEED}
    assert {joints[j.name].limit.effort for j in hand.joints} == {JOINT_TORQUE}


def test_the_allegro_pinch_closes_in_a_few_tenths_of_a_second(monkeypatch: pytest.MonkeyPatch) -> None:
    """The MuJoCo trial's closing of the pinch, counted in its steps without gravity: at 7 rad/s 0.30 s (the
    trial's cost a grasp follows it: 118 ms of CPU at 0.5 rad/s on bench/mujoco_protocols.py's objects, 42 ms)."""
    hand, obj, grasp = allegro_pinch()
    s = MujocoSettings()
    closing = []
    step = mujoco.mj_step

    def counting(m, d) -> None:  # type: ignore[no-untyped-def]
        step(m, d)
        if not np.any(m.opt.gravity):
            closing.append(1)

    monkeypatch.setattr(mujoco, "mj_step", counting)
    result = mujoco_trial.trial(hand, obj, grasp, s)
    monkeypatch.undo()
    assert result.reason != "no_contact" and result.fingers_in_contact >= 1
    assert 0 < len(closing) * s.timestep < PINCH_CLOSING


@pytest.mark.parametrize("recorded, settings", [(mujoco_trial.recorded, MujocoSettings()),
                                                (shake.recorded, ShakeSettings())])
def test_an_allegro_verdict_made_with_the_slower_hand_is_not_kept(recorded, settings) -> None:  # type: ignore[no-untyped-def]
    """A stored verdict records the motors it was made with: the Allegro's before 2026-12-06 (0.5 rad/s) are
    another trial's, so `grasp validate` tries those grasps again."""
    now = load_hand("allegro")
    before = replace(now, actuators=replace(now.actuators, closing_speed=0.5))
    assert recorded(settings, before) != recorded(settings, now)
