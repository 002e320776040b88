"""The load's motion: it starts at the grasp, lifts against gravity, turns
about the tool centre point (which stays put) and shakes with the peak
accelerations its settings name."""

from __future__ import annotations

import numpy as np
from helpers import assert_close

from planner.validation.mujoco_load import load_path, motion
from planner.validation.mujoco_settings import MujocoSettings

#: [m] and [rad] positions and angles from the path's arithmetic (sums of sines and cosines).
TOL = 1e-9


def _path(s: MujocoSettings):  # type: ignore[no-untyped-def]
    pose = np.eye(4)
    pose[:3, 3] = (0.01, 0.02, 0.2)
    tcp, approach, down = np.array([0.0, 0.0, 0.1]), np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, -1.0])
    return pose, tcp, load_path(s, pose, tcp, approach, down)


def test_the_path_starts_at_the_grasp_lifts_and_ends_still_at_the_top() -> None:
    s = MujocoSettings(shake_together=False, hold_time=0.03)
    pose, _, path = _path(s)
    steps = round(s.ramp_time / s.timestep)
    assert_close(path[:steps], np.repeat(pose[None], steps, axis=0), TOL)
    top = pose.copy()
    top[2, 3] += s.lift
    hold = round(s.hold_time / s.timestep)
    assert_close(path[-hold:], np.repeat(top[None], hold, axis=0), TOL)
    shake = round(s.shake_cycles / s.shake_frequency / s.timestep)
    assert len(path) == steps + round(s.lift_time / s.timestep) + 3 * shake + hold


def test_the_turns_keep_the_tool_centre_point_and_reach_the_named_peak_acceleration() -> None:
    s = MujocoSettings(shake_together=False)  # one turn after another
    pose, tcp, path = _path(s)
    start = round(s.ramp_time / s.timestep) + round(s.lift_time / s.timestep)
    n = round(1 / s.shake_frequency / s.timestep)
    turns = path[start:start + 2 * n]
    centres = turns[:, :3, :3] @ tcp + turns[:, :3, 3]
    assert_close(centres, np.repeat(centres[:1], len(centres), axis=0), TOL)
    angles = np.array([motion(path[start - 1], t)[1] for t in turns[:n]])
    # the steps sample the sine: the nearest to its peak is at most half a step away
    sampling = 1.0 - np.cos(np.pi * s.shake_frequency * s.timestep)
    assert_close(angles.max(), s.shake_angle, 1.01 * sampling * s.shake_angle)
    assert angles.max() <= s.shake_angle
    peak = s.shake_angle * (2 * np.pi * s.shake_frequency) ** 2  # [rad/s^2] of a sine of that amplitude
    assert_close(peak, 31.6, 0.5)  # as +-0.2 rad at 2 Hz, the shake the settings were first chosen with


def test_a_shake_together_is_one_cycle_of_both_turns_and_the_push_at_once() -> None:
    s = MujocoSettings(shake_together=True)
    pose, tcp, path = _path(s)
    ramp, lift = round(s.ramp_time / s.timestep), round(s.lift_time / s.timestep)
    n, hold = round(1 / s.shake_frequency / s.timestep), round(s.hold_time / s.timestep)
    assert len(path) == ramp + lift + n + hold
    top, shake = path[ramp + lift - 1], path[ramp + lift:ramp + lift + n]
    wave = np.sin(2 * np.pi * s.shake_frequency * s.timestep * np.arange(1, n + 1))
    down = np.array([0.0, 0.0, -1.0])
    centres = shake[:, :3, :3] @ tcp + shake[:, :3, 3]
    # the tool centre point moves only along gravity, by the push's sine
    assert_close(centres - np.outer(s.shake_distance * wave, down), np.repeat(
        (top[:3, :3] @ tcp + top[:3, 3])[None], n, axis=0), TOL)
    # both turns at once: about an axis across the approach, by up to sqrt(2) of each one's angle
    angles = np.array([motion(top, t)[1] for t in shake])
    assert s.shake_angle < angles.max() <= np.sqrt(2) * s.shake_angle * (1 + 1e-6)
    peak = int(np.argmax(angles))
    relative = shake[peak, :3, :3] @ top[:3, :3].T
    axis = np.array([relative[2, 1] - relative[1, 2], relative[0, 2] - relative[2, 0], relative[1, 0] - relative[0, 1]])
    approach = top[:3, :3] @ np.array([0.0, 0.0, 1.0])
    assert abs(axis @ approach) / np.linalg.norm(axis) < s.shake_angle  # across it, to second order


def test_a_hold_of_no_time_adds_no_step() -> None:
    s = MujocoSettings(hold_time=0.0)
    _, _, path = _path(s)
    assert len(path) == round(s.ramp_time / s.timestep) + round(s.lift_time / s.timestep) + \
        round(1 / s.shake_frequency / s.timestep)

