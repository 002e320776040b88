"""Physical validation: a dynamic PyBullet trial of a stored grasp.

The object is free (real mass, centre of mass and inertia from its mesh and
density; convex parts from :mod:`planner.geometry.decompose`); the hand is held at
the grasp pose by a fixed constraint with its fingers just short of the
planned grasp, then the fingers close under position control limited to the
hand's ``finger_force`` (squeezing past the contact configuration). Then, with the hand held still,
a force of 1 g x mass tugs the object along +-x, +-y, +-z in turn (six
directions, as DexGraspNet), and finally the hand shakes: it oscillates
along and about each of its three axes while the object feels gravity (-z).

Success: at the end the object still touches at least two fingers (links
other than the palm), and it moved less than ``max_translation`` and
``max_rotation`` relative to the hand since the fingers closed. Stored, as
ACRONYM does: the object's motion (linear [m], angular [rad]) during closing
(in the world) and during the tugs and shaking (relative to the hand).
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass

import numpy as np

from planner.geometry.decompose import convex_parts
from planner.geometry.frames import angle_between, rotation_from_rotvec
from planner.geometry.solid import PreparedObject
from planner.grasp import Grasp, Trial
from planner.sim import Sim
from planner.sim.dynamics import Dynamics
from planner.specs.hands import HandSpec
from planner.validation.tolerances import FINAL_HOLD, GRAVITY, RAD_PER_M, TUG_DIRECTIONS


@dataclass(frozen=True)
class TrialSettings:
    """Everything that decides a trial (stored with each result)."""

    dt: float = 1.0 / 240.0  # [s]
    solver_iterations: int = 150
    close_time: float = 0.6  # [s] fingers closing
    settle_time: float = 0.2  # [s] before the tugs
    tug_time: float = 0.3  # [s] per direction
    shake_time: float = 0.5  # [s] per axis (3 translations, 3 rotations)
    shake_amplitude: float = 0.02  # [m]
    shake_angle: float = 0.3  # [rad]
    shake_frequency: float = 2.0  # [Hz]
    squeeze: float = 0.01  # [m] prismatic / 10x that [rad] revolute, past the contact configuration
    start_opening: float = 0.005  # [m] prismatic / 10x that [rad] revolute, short of the contact configuration
    hold_force: float = 2000.0  # [N] of the constraint holding the hand
    max_translation: float = 0.02  # [m] relative to the hand
    max_rotation: float = 0.35  # [rad] relative to the hand
    min_fingers: int = 2
    overlap_tol: float = 0.0005  # [m] initial overlap tolerated before backing the hand off
    back_off_step: float = 0.0005  # [m]
    max_back_off: float = 0.01  # [m]

    def to_json(self) -> str:
        return json.dumps(asdict(self), sort_keys=True)


def trial(hand: HandSpec, obj: PreparedObject, grasp: Grasp, settings: TrialSettings | None = None,
          friction: float | None = None, mass: float | None = None) -> Trial:
    """Run one trial. ``friction``/``mass`` override the object's (tests)."""
    s = settings or TrialSettings()
    parts = convex_parts(obj.mesh, obj.mesh_hash)
    m = obj.mass if mass is None else mass
    inertia = obj.inertia * (m / obj.mass)
    mu = obj.friction if friction is None else friction
    with Sim() as sim:
        dyn = Dynamics(sim, s.dt, s.solver_iterations)
        uid = dyn.add_object(parts.vertices, parts.faces, m, obj.com, inertia, mu, np.eye(4))
        body = sim.load_urdf(hand.urdf, fixed=False)
        dyn.set_friction(body.uid, mu)
        pose = np.array(grasp.pose, float)
        sim.set_joints(body, _start(hand, grasp, s.start_opening))
        pose = _clear(dyn, sim, body, uid, pose, hand.approach, s)
        cid = dyn.hold(body, pose, s.hold_force)
        targets = _squeezed(hand, grasp, s.squeeze)
        start = dyn.object_pose(uid)
        dyn.drive(body, targets, hand.finger_force)
        _run(dyn, s.close_time)
        closed = dyn.object_pose(uid)
        closing_lin = float(np.linalg.norm(closed[:3, 3] - start[:3, 3]))
        closing_ang = angle_between(start[:3, :3], closed[:3, :3])
        _run(dyn, s.settle_time)
        hand_pose = sim.link_pose(body, hand.root_link)
        rel0 = np.linalg.inv(hand_pose) @ dyn.object_pose(uid)
        weight = m * GRAVITY
        for direction in TUG_DIRECTIONS:
            _run(dyn, s.tug_time, lambda d=direction: dyn.push(uid, weight * d))
        for axis in range(6):
            _shake(dyn, cid, pose, axis, s, lambda: dyn.push(uid, weight * TUG_DIRECTIONS[5]))
        dyn.move_hold(cid, pose, s.hold_force)
        _run(dyn, FINAL_HOLD, lambda: dyn.push(uid, weight * TUG_DIRECTIONS[5]))
        hand_pose = sim.link_pose(body, hand.root_link)
        rel1 = np.linalg.inv(hand_pose) @ dyn.object_pose(uid)
        root = body.links[hand.root_link]
        fingers = len({link for link in dyn.touching_links(body, uid) if link != root})
    lin = float(np.linalg.norm(rel1[:3, 3] - rel0[:3, 3]))
    ang = angle_between(rel0[:3, :3], rel1[:3, :3])
    ok = fingers >= s.min_fingers and lin < s.max_translation and ang < s.max_rotation
    return Trial(bool(ok), fingers, closing_lin, closing_ang, lin, ang)


def _clear(dyn: Dynamics, sim: Sim, body, uid: int, pose: np.ndarray, approach: np.ndarray,  # type: ignore[no-untyped-def]
           s: TrialSettings) -> np.ndarray:
    """Back the open hand off along its approach until it does not overlap the
    object's convex parts (they are a little fatter than the exact mesh the
    grasp was planned on), at most ``max_back_off``."""
    pose = pose.copy()
    direction = pose[:3, :3] @ approach
    moved = 0.0
    sim.set_pose(body, pose)
    while dyn.overlap(body, uid) > s.overlap_tol and moved < s.max_back_off:
        pose[:3, 3] -= direction * s.back_off_step
        moved += s.back_off_step
        sim.set_pose(body, pose)
    return pose


def _start(hand: HandSpec, grasp: Grasp, opening: float) -> dict[str, float]:
    """The fingers just short of the planned grasp: the closed values moved back
    towards the open preshape by ``opening`` (m, or 10x that in rad), so the
    trial tests holding the grasp, not a long swing that knocks the object."""
    out = {}
    for joint in hand.joints:
        closed = grasp.closed_joints.get(joint.name, joint.lower)
        opened = grasp.open_joints.get(joint.name, closed)
        step = opening * (RAD_PER_M if joint.kind == "revolute" else 1.0)
        out[joint.name] = float(closed + np.clip(opened - closed, -step, step))
    return out


def _squeezed(hand: HandSpec, grasp: Grasp, squeeze: float) -> dict[str, float]:
    """Closed joint values pushed further along the closing direction, in limits."""
    out = {}
    for joint in hand.joints:
        rate = joint.close
        if joint.mimic is not None:
            rate = hand.joint(joint.mimic).close * joint.multiplier
        step = squeeze * (RAD_PER_M if joint.kind == "revolute" else 1.0) * float(np.sign(rate))
        value = grasp.closed_joints.get(joint.name, joint.lower) + step
        out[joint.name] = float(np.clip(value, joint.lower, joint.upper))
    return out


def _run(dyn: Dynamics, seconds: float, each_step=None) -> None:  # type: ignore[no-untyped-def]
    for _ in range(max(1, int(round(seconds / dyn.dt)))):
        if each_step is not None:
            each_step()
        dyn.step()


def _shake(dyn: Dynamics, cid: int, pose: np.ndarray, axis: int, s: TrialSettings, each_step) -> None:  # type: ignore[no-untyped-def]
    steps = max(1, int(round(s.shake_time / dyn.dt)))
    for k in range(steps):
        phase = np.sin(2 * np.pi * s.shake_frequency * k * dyn.dt)
        moved = pose.copy()
        if axis < 3:
            moved[:3, 3] += pose[:3, axis] * s.shake_amplitude * phase
        else:
            turn = rotation_from_rotvec(pose[:3, axis - 3] * s.shake_angle * phase)
            moved[:3, :3] = turn @ pose[:3, :3]
        dyn.move_hold(cid, moved, s.hold_force)
        each_step()
        dyn.step()
