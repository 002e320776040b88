"""MoveIt grasps: one YAML file per (object, hand) of ``moveit_msgs/Grasp`` messages.

MoveIt's pick pipeline (and MoveIt Task Constructor's grasp stages) take a
list of ``moveit_msgs/Grasp``; this export writes them in rank order, as the
YAML a ROS 2 node loads and fills a message from, field for field::

    DIR/moveit/{hand}/{object}.yaml
    - id: "{object}/{hand}/{rank}"
      pre_grasp_posture: {header: {frame_id: ""}, joint_names: [...], points: [{positions: [...],
                          velocities: [], accelerations: [], effort: [], time_from_start: {sec, nanosec}}]}
      grasp_posture: ... the same, closed
      grasp_pose: {header: {frame_id: "{object}"}, pose: {position: {x, y, z}, orientation: {x, y, z, w}}}
      grasp_quality: the score
      pre_grasp_approach: {direction: {header: {frame_id: "{ee_link}"}, vector: {x, y, z}},
                           desired_distance, min_distance}
      post_grasp_retreat: ... the reverse direction, same distances
      post_place_retreat: ... the same
      max_contact_force: 0 (no limit)
      allowed_touch_objects: ["{object}"]

Frames: ``grasp_pose`` is the pose of the arm's end-effector link
(``[arm] ee_link`` of hand.toml: what MoveIt moves; the hand frame times the
inverse of the hand's mount) in the object frame, so ``header.frame_id`` is
the object's name: a planning scene that knows the object by that name
places the grasp on it. The approach and retreat directions are in the
end-effector frame, along the hand's approach axis (retreat: against it),
``desired_distance`` the planner's pre-grasp distance (0.10 m, the one the
reachability check backs off by) and ``min_distance`` half of it. Postures
name every finger joint of the hand (mimic joints included, as a joint
state lists them) at the open preshape and at the closed grasp, radians or
metres, each reached 0.5 s after its start. Durations are ROS 2's
``builtin_interfaces/Duration`` (``sec``, ``nanosec``).
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from planner.datasets import registry
from planner.datasets.acronym import joint_names
from planner.datasets.meshes import ExportedObject
from planner.geometry.quaternion import canonical_xyzw
from planner.plan.tolerances import PREGRASP_DISTANCE
from planner.record.grasp import Grasp
from planner.specs.hands import HandSpec

SUFFIX = ".yaml"
POSTURE_TIME = 0.5  # [s] time_from_start of each posture's one point
MIN_DISTANCE = PREGRASP_DISTANCE / 2  # [m] the approach and retreat must cover at least this


def relative_path(stem: str, hand: str) -> str:
    return f"moveit/{hand}/{stem}{SUFFIX}"


def end_effector_pose(grasp_pose: np.ndarray, hand: HandSpec) -> np.ndarray:
    """(4, 4) the arm's end-effector link in the object frame for a grasp
    pose (the hand frame); the hand frame itself for a hand without an arm."""
    mount = np.eye(4) if hand.arm is None else hand.arm.mount
    return np.asarray(grasp_pose, float) @ np.linalg.inv(mount)


def _vector(v: np.ndarray) -> dict:
    """x, y, z of ``v`` (3,); a negative zero (the retreat, ``-approach``, of an axis-aligned approach) written
    as 0.0: "-0.0" reads as a sign bug to whoever opens the file."""
    return {"x": float(v[0]) + 0.0, "y": float(v[1]) + 0.0, "z": float(v[2]) + 0.0}


def _posture(names: list[str], joints: dict[str, float]) -> dict:
    seconds = int(POSTURE_TIME)
    return {"header": {"frame_id": ""}, "joint_names": names,
            "points": [{"positions": [float(joints.get(n, 0.0)) for n in names], "velocities": [],
                        "accelerations": [], "effort": [],
                        "time_from_start": {"sec": seconds, "nanosec": int(round((POSTURE_TIME - seconds) * 1e9))}}]}


def _translation(frame: str, direction: np.ndarray) -> dict:
    return {"direction": {"header": {"frame_id": frame}, "vector": _vector(direction)},
            "desired_distance": float(PREGRASP_DISTANCE), "min_distance": float(MIN_DISTANCE)}


def message(g: Grasp, hand: HandSpec) -> dict:
    """One ``moveit_msgs/Grasp`` as a plain dict (see the module docstring)."""
    ee = end_effector_pose(g.pose, hand)
    ee_link = hand.root_link if hand.arm is None else hand.arm.ee_link
    mount = np.eye(4) if hand.arm is None else hand.arm.mount
    approach = mount[:3, :3] @ hand.approach  # the hand's approach axis in the end-effector frame
    names = joint_names(hand)
    q = canonical_xyzw(ee[:3, :3])
    return {"id": f"{g.object}/{g.hand}/{g.rank}",
            "pre_grasp_posture": _posture(names, hand.posture(g.open_joints)),
            "grasp_posture": _posture(names, hand.posture(g.closed_joints)),
            "grasp_pose": {"header": {"frame_id": g.object},
                           "pose": {"position": _vector(ee[:3, 3]),
                                    "orientation": {**_vector(q), "w": float(q[3]) + 0.0}}},
            "grasp_quality": float(g.score or 0.0),
            "pre_grasp_approach": _translation(ee_link, approach),
            "post_grasp_retreat": _translation(ee_link, -approach),
            "post_place_retreat": _translation(ee_link, -approach),
            "max_contact_force": 0.0,
            "allowed_touch_objects": [g.object]}


def _dumper(pure: bool = False) -> type:
    """PyYAML's safe dumper writing every value in full: without it the joint names both postures of a message
    share become an anchor and an alias (``&id001`` ... ``*id001``), numbered from ``id001`` again by each
    batch's dump, so a file of more than one batch (a pair of over 5,000 grasps) held duplicate anchors,
    which ``yaml.safe_load`` refuses. libyaml's emitter where PyYAML has it (the same text; the pure-Python one
    wrote 189 grasps a second, 44.6 s of a 6-object export whose other formats took 2-3 s), unless ``pure``."""
    import yaml

    base = yaml.SafeDumper if pure or not yaml.__with_libyaml__ else yaml.CSafeDumper

    class Dumper(base):  # type: ignore[valid-type, misc]
        def ignore_aliases(self, data: object) -> bool:
            return True

    return Dumper


def write(path: Path, info: ExportedObject, hand: HandSpec, batches: Iterable[list[Grasp]]) -> int:
    """Write the file (atomically), one YAML document: the list of messages in rank order, with no anchors
    or aliases (:func:`_dumper`)."""
    import yaml

    dumper = _dumper()
    tmp = path.with_name(path.name + ".tmp")
    total = 0
    with open(tmp, "w", encoding="utf-8") as fh:
        fh.write(f"# moveit_msgs/Grasp list: {info.name} with {hand.name}; grasp_pose = the arm's end-effector "
                 f"link in the object frame (see planner/datasets/moveit.py)\n")
        for batch in batches:
            ranked = [g for g in batch if g.rank is not None]
            if ranked:
                yaml.dump([message(g, hand) for g in ranked], fh, Dumper=dumper, sort_keys=False,
                          default_flow_style=None)
            total += len(ranked)
        if total == 0:
            fh.write("[]\n")
    os.replace(tmp, path)
    return total


registry.register("moveit", registry.PairWriter(relative_path, write))
