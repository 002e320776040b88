"""The PyBullet adapter: the only module that imports pybullet.

Everything is kinematic here (bodies are placed, never stepped) except where
a caller asks for dynamics. Poses are 4x4 homogeneous matrices [m]; PyBullet
quaternions (x, y, z, w) never leave this module.
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh.transformations as tf

from planner.errors import SimulationError


def _import_quietly():  # type: ignore[no-untyped-def]
    """pybullet prints its build time on stderr at import, from C; keep the
    CLI's stderr for real messages by pointing fd 2 at /dev/null meanwhile."""
    sys.stderr.flush()
    saved = os.dup(2)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 2)
        import pybullet
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(devnull)
    return pybullet


pb = _import_quietly()


@dataclass(frozen=True)
class Closest:
    """Closest-point pairs between two bodies (a batch of k pairs).

    Attributes:
        links: (k,) link index on body A (-1 = base).
        distance: (k,) signed distance [m]; negative means penetration.
        on_a: (k, 3) point on A [m], world frame.
        on_b: (k, 3) point on B [m], world frame.
        normal_b: (k, 3) unit normal on B pointing from B towards A.
    """

    links: np.ndarray
    distance: np.ndarray
    on_a: np.ndarray
    on_b: np.ndarray
    normal_b: np.ndarray

    def __len__(self) -> int:
        return len(self.distance)

    @property
    def min_distance(self) -> float:
        return float(self.distance.min()) if len(self.distance) else np.inf


_EMPTY = Closest(np.zeros(0, int), np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)))


@dataclass(frozen=True)
class Body:
    """A loaded multibody: its id and the name maps of its links and joints."""

    uid: int
    links: dict[str, int]  # link name -> link index (-1 for the base)
    joints: dict[str, int]  # joint name -> joint index
    joint_axes: dict[str, np.ndarray]  # joint name -> (3,) axis in the child link frame
    inertial: np.ndarray  # (4, 4) base centre-of-mass frame in the base link frame


def pose_to_pb(pose: np.ndarray) -> tuple[list[float], list[float]]:
    """(position, quaternion x-y-z-w) of a 4x4 pose, for PyBullet. It runs on
    every simulator move (tens per closing candidate), so it uses trimesh's
    conversion: measured ~5x cheaper per call than scipy's ``Rotation``,
    which the rest of the project uses (:mod:`planner.geometry.frames`)."""
    w, x, y, z = tf.quaternion_from_matrix(pose)
    return pose[:3, 3].tolist(), [x, y, z, w]


def pb_to_pose(position: tuple, quaternion: tuple) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, :3] = np.reshape(pb.getMatrixFromQuaternion(quaternion), (3, 3))
    pose[:3, 3] = position
    return pose


class Sim:
    """One headless PyBullet world (``p.DIRECT``); use as a context manager."""

    def __init__(self) -> None:
        self.client = pb.connect(pb.DIRECT)
        if self.client < 0:
            raise SimulationError("cannot start a PyBullet DIRECT client")

    def __enter__(self) -> Sim:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        if self.client >= 0:
            pb.disconnect(self.client)
            self.client = -1

    def add_static_mesh(self, vertices: np.ndarray, faces: np.ndarray, pose: np.ndarray | None = None) -> int:
        """A fixed body colliding as the exact (possibly concave) triangle mesh."""
        shape = pb.createCollisionShape(
            pb.GEOM_MESH, vertices=np.asarray(vertices, float).tolist(),
            indices=np.asarray(faces, int).reshape(-1).tolist(), flags=pb.GEOM_FORCE_CONCAVE_TRIMESH,
            physicsClientId=self.client)
        if shape < 0:
            raise SimulationError("PyBullet refused the object mesh")
        position, orientation = pose_to_pb(np.eye(4) if pose is None else pose)
        return pb.createMultiBody(0.0, shape, basePosition=position, baseOrientation=orientation,
                                  physicsClientId=self.client)

    def load_urdf(self, path: Path, *, fixed: bool = True, self_collision: bool = False) -> Body:
        flags = pb.URDF_USE_SELF_COLLISION if self_collision else 0
        try:
            uid = pb.loadURDF(str(path), useFixedBase=fixed, flags=flags, physicsClientId=self.client)
        except pb.error as exc:
            raise SimulationError(f"{path}: PyBullet cannot load this URDF ({exc})") from exc
        base = pb.getBodyInfo(uid, physicsClientId=self.client)[0].decode()
        links, joints, axes = {base: -1}, {}, {}
        for index in range(pb.getNumJoints(uid, physicsClientId=self.client)):
            info = pb.getJointInfo(uid, index, physicsClientId=self.client)
            links[info[12].decode()] = index
            joints[info[1].decode()] = index
            axes[info[1].decode()] = np.asarray(info[13], float)
        info = pb.getDynamicsInfo(uid, -1, physicsClientId=self.client)
        return Body(uid, links, joints, axes, pb_to_pose(info[3], info[4]))

    def set_pose(self, body: Body, pose: np.ndarray) -> None:
        """Place the base *link frame* at ``pose`` (PyBullet itself places the
        base's centre of mass, hence the inertial offset)."""
        position, orientation = pose_to_pb(pose @ body.inertial)
        pb.resetBasePositionAndOrientation(body.uid, position, orientation, physicsClientId=self.client)

    def set_joints(self, body: Body, values: dict[str, float]) -> None:
        for name, value in values.items():
            pb.resetJointState(body.uid, body.joints[name], value, physicsClientId=self.client)

    def link_pose(self, body: Body, link: str) -> np.ndarray:
        index = body.links[link]
        if index < 0:
            position, orientation = pb.getBasePositionAndOrientation(body.uid, physicsClientId=self.client)
            return pb_to_pose(position, orientation) @ np.linalg.inv(body.inertial)
        else:
            state = pb.getLinkState(body.uid, index, computeForwardKinematics=True, physicsClientId=self.client)
            position, orientation = state[4], state[5]
        return pb_to_pose(position, orientation)

    def has_collision(self, body: Body, link: str) -> bool:
        return bool(pb.getCollisionShapeData(body.uid, body.links[link], physicsClientId=self.client))

    def joint_axis_in_base(self, body: Body, joint: str) -> np.ndarray:
        """(3,) axis of a prismatic joint in the base link frame (constant)."""
        child = pb.getJointInfo(body.uid, body.joints[joint], physicsClientId=self.client)[12].decode()
        base = self.link_pose(body, next(n for n, i in body.links.items() if i == -1))
        return base[:3, :3].T @ self.link_pose(body, child)[:3, :3] @ body.joint_axes[joint]

    def add_box(self, half_extents: tuple[float, float, float], pose: np.ndarray) -> int:
        """A fixed box (e.g. a table)."""
        shape = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=list(half_extents), physicsClientId=self.client)
        position, orientation = pose_to_pb(pose)
        return pb.createMultiBody(0.0, shape, basePosition=position, baseOrientation=orientation,
                                  physicsClientId=self.client)

    def set_base_pose(self, uid: int, pose: np.ndarray) -> None:
        """Place a body created here (no inertial offset) at ``pose``."""
        position, orientation = pose_to_pb(pose)
        pb.resetBasePositionAndOrientation(uid, position, orientation, physicsClientId=self.client)

    def joint_limits(self, body: Body, joint: str) -> tuple[float, float]:
        info = pb.getJointInfo(body.uid, body.joints[joint], physicsClientId=self.client)
        return float(info[8]), float(info[9])

    def movable_joints(self, body: Body) -> list[str]:
        """Names of the revolute/prismatic joints, in PyBullet's DOF order."""
        out = []
        for index in range(pb.getNumJoints(body.uid, physicsClientId=self.client)):
            info = pb.getJointInfo(body.uid, index, physicsClientId=self.client)
            if info[2] in (pb.JOINT_REVOLUTE, pb.JOINT_PRISMATIC):
                out.append(info[1].decode())
        return out

    def joint_values(self, body: Body, names: list[str]) -> list[float]:
        return [pb.getJointState(body.uid, body.joints[n], physicsClientId=self.client)[0] for n in names]

    def inverse_kinematics(self, body: Body, link: str, pose: np.ndarray, lower: list[float] | None = None,
                           upper: list[float] | None = None, rest: list[float] | None = None,
                           iterations: int = 200) -> list[float]:
        """PyBullet's damped least-squares IK from the current joint state; one
        value per movable joint (PyBullet's DOF order). With limits and rest
        poses it uses the null-space variant (stays inside limits, but stops a
        few millimetres short); without, the plain one (converges tightly)."""
        position, orientation = pose_to_pb(pose)
        extra = {}
        if lower is not None and upper is not None and rest is not None:
            extra = dict(lowerLimits=lower, upperLimits=upper, jointRanges=[u - lo for lo, u in zip(lower, upper)],
                         restPoses=rest)
        return list(pb.calculateInverseKinematics(
            body.uid, body.links[link], position, orientation, maxNumIterations=iterations, residualThreshold=1e-8,
            physicsClientId=self.client, **extra))

    def jacobian(self, body: Body, link: str, dof_values: list[float]) -> np.ndarray:
        """(6, n_dof) geometric Jacobian of ``link``'s frame origin (linear; angular)."""
        zeros = [0.0] * len(dof_values)
        linear, angular = pb.calculateJacobian(body.uid, body.links[link], [0.0, 0.0, 0.0], list(dof_values),
                                               zeros, zeros, physicsClientId=self.client)
        return np.vstack([np.asarray(linear), np.asarray(angular)])

    def add_visual_mesh(self, vertices: np.ndarray, faces: np.ndarray, rgba: tuple[float, ...],
                        pose: np.ndarray | None = None) -> int:
        """A body that is only seen (no collision), for pictures."""
        tri = np.asarray(faces, int)
        shape = pb.createVisualShape(pb.GEOM_MESH, vertices=np.asarray(vertices, float).tolist(),
                                     indices=tri.reshape(-1).tolist(), rgbaColor=list(rgba),
                                     physicsClientId=self.client)
        position, orientation = pose_to_pb(np.eye(4) if pose is None else pose)
        return pb.createMultiBody(0.0, -1, shape, basePosition=position, baseOrientation=orientation,
                                  physicsClientId=self.client)

    def set_color(self, body: Body, rgba: tuple[float, ...]) -> None:
        for index in body.links.values():
            pb.changeVisualShape(body.uid, index, rgbaColor=list(rgba), physicsClientId=self.client)

    def render(self, eye: np.ndarray, target: np.ndarray, up: np.ndarray, size: tuple[int, int],
               fov: float = 40.0, near: float = 0.01, far: float = 5.0) -> np.ndarray:
        """(h, w, 3) uint8 RGB picture from PyBullet's CPU TinyRenderer."""
        width, height = size
        view = pb.computeViewMatrix(list(eye), list(target), list(up), physicsClientId=self.client)
        proj = pb.computeProjectionMatrixFOV(fov, width / height, near, far, physicsClientId=self.client)
        _, _, rgba, _, _ = pb.getCameraImage(width, height, view, proj, renderer=pb.ER_TINY_RENDERER,
                                             lightDirection=[1, 1, 2], shadow=0, physicsClientId=self.client)
        return np.reshape(np.asarray(rgba, np.uint8), (height, width, 4))[:, :, :3]

    def link_aabb(self, body: Body, link: str) -> tuple[np.ndarray, np.ndarray]:
        lo, hi = pb.getAABB(body.uid, body.links[link], physicsClientId=self.client)
        return np.asarray(lo), np.asarray(hi)

    def closest(self, a: int, b: int, max_distance: float, link_a: int | None = None) -> Closest:
        """Closest-point pairs between bodies ``a`` and ``b`` within ``max_distance`` [m]."""
        kwargs = {} if link_a is None else {"linkIndexA": link_a}
        rows = pb.getClosestPoints(a, b, max_distance, physicsClientId=self.client, **kwargs)
        if not rows:
            return _EMPTY
        links, _, on_a, on_b, normal_b, distance = zip(*(r[3:9] for r in rows))
        return Closest(np.array(links, int), np.array(distance, float), np.array(on_a, float),
                       np.array(on_b, float), np.array(normal_b, float))
