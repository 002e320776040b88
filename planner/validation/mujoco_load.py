"""The load of the MuJoCo trial (:mod:`planner.validation.mujoco_trial`) as
motion: the hand's target pose at every step (ramp, lift, shake, hold) and
the measure of how far the object moved relative to the hand. Pure numpy;
frames are the world (= the object's at rest), poses (4, 4) [m].
"""

from __future__ import annotations

import math

import numpy as np

from planner.geometry.frames import UP
from planner.validation.mujoco_settings import MujocoSettings


def steps(seconds: float, dt: float) -> int:
    """Time steps of ``dt`` [s] in a phase of ``seconds`` [s]: the nearest whole number, at least 1; none in a
    phase of no time (the trial's settle or hold switched off)."""
    return 0 if seconds == 0 else max(1, int(round(seconds / dt)))


def load_path(s: MujocoSettings, pose: np.ndarray, tcp: np.ndarray, approach: np.ndarray,
              down: np.ndarray) -> np.ndarray:
    """(n, 4, 4) the hand's target pose at every step of the load from the grasp ``pose``: ramp
    (still), lift against ``down`` (3,), rotations about the two axes across the hand's unit
    ``approach`` (hand frame) through the tool centre point ``tcp`` (hand frame), translation along
    ``down`` (one after another, or all at once if ``shake_together``), hold (still)."""
    dt = s.timestep
    still = np.repeat(pose[None], steps(s.ramp_time, dt), axis=0)
    n = steps(s.lift_time, dt)
    lift = np.repeat(pose[None], n, axis=0)
    lift[:, :3, 3] -= np.outer(s.lift * 0.5 * (1.0 - np.cos(np.pi * np.arange(1, n + 1) / n)), down)
    top = lift[-1]
    centre = top[:3, :3] @ tcp + top[:3, 3]
    n = steps(s.shake_cycles / s.shake_frequency, dt) if s.shake_cycles else 0
    wave = np.sin(2 * np.pi * s.shake_frequency * dt * np.arange(1, n + 1))
    turns = [_rotations(top[:3, :3] @ axis, s.shake_angle * wave) for axis in _across(approach)]
    if s.shake_together:  # one cycle of both turns and the push at once
        turns = [turns[0] @ turns[1]]
    shakes = []
    for rotation in turns:
        turn = np.repeat(np.eye(4)[None], n, axis=0)
        turn[:, :3, :3] = rotation
        turn[:, :3, 3] = centre - rotation @ centre
        shakes.append(turn @ top)
    shift = shakes.pop() if s.shake_together else np.repeat(top[None], n, axis=0)  # the push, on the turn or alone
    shift[:, :3, 3] += np.outer(s.shake_distance * wave, down)
    shakes.append(shift)
    hold = np.repeat(top[None], steps(s.hold_time, dt), axis=0)
    return np.concatenate([still, lift, *shakes, hold])


def down_along(name: str, approach: np.ndarray, up: np.ndarray = UP) -> np.ndarray:
    """(3,) unit vector, world (= object) frame, of :data:`~planner.validation.mujoco_settings.DOWN`'s
    ``name``; ``approach``: the hand's approach in the world. "-z" (and "none": without gravity the hand
    still lifts and shakes along it) is the object's down as it rests, -``up``: the object's own
    (``PreparedObject.up``; the object frame's -z, -:data:`~planner.geometry.frames.UP`, unless told), or for a
    grasp planned on a table the table's down (:func:`~planner.geometry.frames.resting_up`)."""
    if name == "approach":
        return approach / np.linalg.norm(approach)
    return np.array([0.0, -1.0, 0.0]) if name == "-y" else 0.0 - up  # not -up: no negative zeros


def motion(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """(distance [m], angle [rad]) between two (4, 4) frames (the angle from
    the trace: ~1e-4 rad resolution near 0, plenty for a verdict)."""
    cos = (float(np.einsum("ij,ij->", a[:3, :3], b[:3, :3])) - 1.0) / 2.0
    shift = b[:3, 3] - a[:3, 3]  # its norm as np.linalg.norm takes it (the root of its dot with itself)
    return float(math.sqrt(shift.dot(shift))), math.acos(min(1.0, max(-1.0, cos)))


def _across(approach: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit axes (hand frame) across the unit ``approach``: the hand's x
    (or y, if x is the approach) made perpendicular, and approach x that."""
    a = np.asarray(approach, float) / np.linalg.norm(approach)
    seed = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    first = seed - (seed @ a) * a
    first /= np.linalg.norm(first)
    return first, np.cross(a, first)


def _rotations(axis: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """(n, 3, 3) rotations by ``angles`` (n,) [rad] about the unit ``axis`` (Rodrigues)."""
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return (np.eye(3) + np.sin(angles)[:, None, None] * k
            + (1 - np.cos(angles))[:, None, None] * (k @ k))
