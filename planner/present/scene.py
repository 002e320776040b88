"""What a picture or a viewer draws of a grasp, as plain meshes with poses.

A :class:`Part` is one triangle mesh in its own frame with the pose that puts
it in the world; a :class:`GraspScene` is everything one grasp shows: the
hand closed (as stored) and open (its preshape's opening at the same pose),
the contacts with their friction cones, the approach, and the arm when the
grasp was reached at a world pose. Building it needs no display backend:
the viewer (:mod:`planner.present.viewer`, viser) and the tests read the same
scene. Hand and arm meshes come from their URDFs at the given joint values,
with yourdfpy's forward kinematics (every joint as the grasp stores it, mimics included).

Frames: the world is the object frame unless an object pose is given
(``object_pose``: the object frame in the world). Metres throughout.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache, partial
from pathlib import Path

import numpy as np
import trimesh
import yourdfpy

from planner.geometry.frames import rotation_onto
from planner.record.grasp import Grasp
from planner.specs.hands import HandSpec

OBJECT_RGB = (217, 140, 64)
HAND_RGB = (140, 153, 179)
OPEN_RGB = (120, 200, 255)
ARM_RGB = (200, 200, 205)
CONTACT_RGB = (230, 15, 15)
CONE_RGB = (25, 190, 50)
APPROACH_RGB = (240, 180, 0)
CONTACT_RADIUS = 0.003  # [m] drawn radius of a contact point
CONE_LENGTH = 0.015  # [m] drawn height of a friction cone
MOVED = 1e-6  # [m] a link of the open hand this close to its closed pose is not drawn twice
APPROACH_LENGTH = 0.08  # [m] drawn length of the approach, ending at the approach point


@dataclass(frozen=True)
class Part:
    """One mesh to draw.

    Attributes:
        name: unique within its scene, '/'-separated (``hand/closed/panda_leftfinger_0``).
        vertices: (n, 3) [m] in the part's own frame; faces: (f, 3) int.
        pose: (4, 4) the part's frame in the world [m].
        rgb: colour, 0-255 each.
    """

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    pose: np.ndarray
    rgb: tuple[int, int, int]

    def __post_init__(self) -> None:
        if self.vertices.ndim != 2 or self.vertices.shape[1] != 3 or self.faces.ndim != 2 \
                or self.faces.shape[1] != 3 or self.pose.shape != (4, 4):
            raise ValueError("Part needs vertices (n, 3), faces (f, 3) and a (4, 4) pose")

    def world_vertices(self) -> np.ndarray:
        """(n, 3) [m] the vertices in the world."""
        return self.vertices @ self.pose[:3, :3].T + self.pose[:3, 3]


@dataclass(frozen=True)
class GraspScene:
    """Everything one grasp shows, world frame.

    Attributes:
        object: the object mesh at its pose.
        closed: the hand's links at the stored closed joints.
        open: the links the opening moves, at the stored open joints (same hand pose).
        contacts: (k, 3) [m] contact points; normals: (k, 3) unit normals into the object (as stored).
        cones: one friction-cone mesh per contact (half-angle atan(mu), opening outwards).
        approach: (2, 3) [m] a segment ending at the approach point, along the approach direction.
        arm: the arm's links at the reaching joints (empty without an object pose).
    """

    object: Part
    closed: tuple[Part, ...]
    open: tuple[Part, ...]
    contacts: np.ndarray
    normals: np.ndarray
    cones: tuple[Part, ...]
    approach: np.ndarray
    arm: tuple[Part, ...] = ()

    def parts(self) -> tuple[Part, ...]:
        return (self.object, *self.closed, *self.open, *self.cones, *self.arm)


@lru_cache(maxsize=8)
def _model(urdf: Path) -> yourdfpy.URDF:
    # mesh paths as the file gives them, absolute, relative or package:// (pybullet_data's arms)
    # resolved against the URDF's folder
    # mimic tags dropped: every joint is set from the configuration drawn (a hand's posture, a broken-away
    # Barrett distal included, whose stored angle is not its coupling's)
    handler = partial(_resolve, folder=urdf.parent)
    robot = yourdfpy.URDF.load(str(urdf), build_scene_graph=False, load_meshes=False, filename_handler=handler).robot
    for joint in robot.joints:
        joint.mimic = None
    return yourdfpy.URDF(robot, build_scene_graph=True, load_meshes=True, filename_handler=handler,
                         build_collision_scene_graph=False, load_collision_meshes=False)


def _resolve(fname: str, folder: Path) -> str:
    """A URDF mesh path: ``package://a/b`` is taken as ``a/b`` under the URDF's folder or one above it."""
    path = fname.removeprefix("package://") if fname.startswith("package://") else fname
    for base in (folder, folder.parent):
        if (base / path).exists():
            return str(base / path)
    return str(Path(path) if Path(path).is_absolute() else folder / path)


def robot_parts(urdf: Path, joints: Mapping[str, float], base: np.ndarray, prefix: str, rgb: tuple[int, int, int],
                skip_below: str | None = None) -> tuple[Part, ...]:
    """The visual meshes of a URDF at ``joints`` [rad or m] (every joint as given, mimics too: a hand's
    :meth:`~planner.specs.hand_spec.HandSpec.posture`; joints not given at 0), its root link at ``base``
    (4, 4) in the world. ``skip_below``: leave out that link and the links
    under it (an arm's own hand, drawn apart)."""
    model = _model(Path(urdf))
    model.update_cfg({name: float(joints.get(name, 0.0)) for name in model.actuated_joint_names})
    scene = model.scene
    skipped = _subtree(model, skip_below) if skip_below else set()
    out = []
    for i, node in enumerate(scene.graph.nodes_geometry):
        link = scene.graph.transforms.parents.get(node)
        if link in skipped:
            continue
        transform, geometry = scene.graph.get(node)
        mesh = scene.geometry[geometry]
        if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
            continue
        out.append(Part(f"{prefix}/{link}_{i}", np.asarray(mesh.vertices, float), np.asarray(mesh.faces, int),
                        base @ transform, rgb))
    return tuple(out)


def _subtree(model: yourdfpy.URDF, top: str) -> set[str]:
    below, frontier = {top}, [top]
    while frontier:
        parent = frontier.pop()
        for joint in model.robot.joints:
            if joint.parent == parent and joint.child not in below:
                below.add(joint.child)
                frontier.append(joint.child)
    return below


def grasp_scene(hand: HandSpec, mesh: trimesh.Trimesh, grasp: Grasp, friction: float,
                object_pose: np.ndarray | None = None, arm_joints: Mapping[str, float] | None = None,
                robot_base: np.ndarray | None = None) -> GraspScene:
    """The scene of ``grasp`` on ``mesh`` (object frame); with ``object_pose``
    (4, 4) the object placed in the world and, with ``arm_joints`` [rad], the
    hand's arm (based at ``robot_base``, default the origin) at them."""
    world = np.eye(4) if object_pose is None else np.asarray(object_pose, float)
    hand_pose = world @ np.asarray(grasp.pose, float)
    obj = object_part(mesh, world)
    closed = robot_parts(hand.urdf, hand.posture(grasp.closed_joints), hand_pose, "hand/closed", HAND_RGB)
    # the open hand: only the links opening moves (the palm is where the closed one is)
    opened = tuple(p for p, c in zip(robot_parts(hand.urdf, hand.posture(grasp.open_joints), hand_pose, "hand/open",
                                                 OPEN_RGB), closed)
                   if not np.allclose(p.pose, c.pose, atol=MOVED))
    points = grasp.contacts.points @ world[:3, :3].T + world[:3, 3]
    normals = grasp.contacts.normals @ world[:3, :3].T
    cones = tuple(_cone(f"contacts/cone_{i}", p, n, friction) for i, (p, n) in enumerate(zip(points, normals)))
    tip = world[:3, :3] @ grasp.approach_point + world[:3, 3]
    direction = world[:3, :3] @ grasp.approach_dir
    approach = np.array([tip - APPROACH_LENGTH * direction, tip])
    arm: tuple[Part, ...] = ()
    if arm_joints is not None and hand.arm is not None:
        base = np.eye(4) if robot_base is None else np.asarray(robot_base, float)
        arm = robot_parts(hand.arm.urdf, arm_joints, base, "arm", ARM_RGB, skip_below=hand.arm.ee_link)
    return GraspScene(obj, closed, opened, points, normals, cones, approach, arm)


def object_part(mesh: trimesh.Trimesh, pose: np.ndarray | None = None) -> Part:
    """The object mesh at ``pose`` (4, 4) in the world (default: the object frame is the world)."""
    return Part("object", np.asarray(mesh.vertices, float), np.asarray(mesh.faces, int),
                np.eye(4) if pose is None else np.asarray(pose, float), OBJECT_RGB)


def _cone(name: str, point: np.ndarray, normal: np.ndarray, mu: float) -> Part:
    """A friction cone with its apex at the contact, opening outwards, about
    minus the inward ``normal`` (the finger pushes along it), half-angle atan(mu)."""
    cone = trimesh.creation.cone(radius=CONE_LENGTH * mu, height=CONE_LENGTH, sections=16)
    cone.apply_translation([0.0, 0.0, -CONE_LENGTH])  # apex at the origin, opening towards -z
    pose = np.eye(4)
    pose[:3, :3] = rotation_onto([0.0, 0.0, -1.0], -normal / np.linalg.norm(normal))
    pose[:3, 3] = point
    return Part(name, np.asarray(cone.vertices, float), np.asarray(cone.faces, int), pose, CONE_RGB)
