"""Dynamic PyBullet scenes: a free object made of convex parts, a hand held
by a fixed constraint that can be moved, finger motors, external forces.
Part of the PyBullet adapter (only ``planner.sim`` imports pybullet)."""

from __future__ import annotations

import numpy as np

from planner import assets
from planner.sim import Body, Sim, pb, pb_to_pose, pose_to_pb

#: [rad/s or m/s] finger motor speed limit: fast enough that revolute fingers
#: close within a trial's closing time (1.0 was too slow for them).
FINGER_SPEED = 3.0
#: [kg m^2] smallest principal moment given to PyBullet: a flat part's eigen
#: solver may return 0 (or -1e-20), which PyBullet rejects.
MIN_MOMENT = 1e-9
#: [m] overlaps shallower than this are resolved by split impulses (position
#: only, no added velocity): a decomposed object starting slightly inside the
#: hand must not be shot away.
SPLIT_IMPULSE_DEPTH = 0.001


def _part_file(vertices: np.ndarray, faces: np.ndarray) -> str:
    """A convex part as a small OBJ file in the cache (PyBullet's compound
    shapes take files, not vertex lists); named by its content."""
    v, f = np.asarray(vertices, float), np.asarray(faces, int)
    path = assets.cache_dir("parts") / f"{assets.sha256_bytes(v.tobytes() + f.tobytes())[:20]}.obj"
    if not path.is_file():
        text = "".join(f"v {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in v)
        text += "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in f)
        assets.atomic_write(path, text.encode())
    return str(path)


class Dynamics:
    """Dynamic operations on one :class:`Sim` (time step ``dt`` [s])."""

    def __init__(self, sim: Sim, dt: float = 1.0 / 240.0, solver_iterations: int = 150) -> None:
        self.sim = sim
        self.c = sim.client
        self.dt = dt
        # split impulses: resolving an overlap must not add velocity (no "explosions"
        # when a decomposed object starts slightly inside the hand)
        pb.setPhysicsEngineParameter(fixedTimeStep=dt, numSolverIterations=solver_iterations, useSplitImpulse=1,
                                     splitImpulsePenetrationThreshold=-SPLIT_IMPULSE_DEPTH, physicsClientId=self.c)
        pb.setGravity(0, 0, 0, physicsClientId=self.c)

    def add_object(self, parts_vertices: tuple[np.ndarray, ...], parts_faces: tuple[np.ndarray, ...], mass: float,
                   com: np.ndarray, inertia: np.ndarray, friction: float, pose: np.ndarray) -> int:
        """A free rigid body made of convex parts (object-frame vertices [m])
        with the given mass [kg], centre of mass and inertia about it (object
        frame, kg m^2), placed with its object frame at ``pose``."""
        files = [_part_file(v, f) for v, f in zip(parts_vertices, parts_faces)]
        shape = pb.createCollisionShapeArray([pb.GEOM_MESH] * len(files), fileNames=files,
                                             physicsClientId=self.c)
        moments, axes = np.linalg.eigh(np.asarray(inertia, float))
        if np.linalg.det(axes) < 0:
            axes[:, 0] *= -1
        frame = np.eye(4)
        frame[:3, :3], frame[:3, 3] = axes, com
        _, inertial_q = pose_to_pb(frame)
        uid = pb.createMultiBody(mass, shape, -1, basePosition=[0, 0, 0], baseInertialFramePosition=list(com),
                                 baseInertialFrameOrientation=inertial_q, physicsClientId=self.c)
        pb.changeDynamics(uid, -1, localInertiaDiagonal=list(np.maximum(moments, MIN_MOMENT)), lateralFriction=friction,
                          spinningFriction=0.0, rollingFriction=0.0, linearDamping=0.0, angularDamping=0.0,
                          physicsClientId=self.c)
        self.set_object_pose(uid, pose)
        return uid

    def set_object_pose(self, uid: int, pose: np.ndarray) -> None:
        """Place the object *frame* at ``pose`` (PyBullet places the inertial frame)."""
        info = pb.getDynamicsInfo(uid, -1, physicsClientId=self.c)
        position, orientation = pose_to_pb(pose @ pb_to_pose(info[3], info[4]))
        pb.resetBasePositionAndOrientation(uid, position, orientation, physicsClientId=self.c)
        pb.resetBaseVelocity(uid, [0, 0, 0], [0, 0, 0], physicsClientId=self.c)

    def object_pose(self, uid: int) -> np.ndarray:
        info = pb.getDynamicsInfo(uid, -1, physicsClientId=self.c)
        position, orientation = pb.getBasePositionAndOrientation(uid, physicsClientId=self.c)
        return pb_to_pose(position, orientation) @ np.linalg.inv(pb_to_pose(info[3], info[4]))

    def hold(self, body: Body, pose: np.ndarray, force: float) -> int:
        """Hold the hand's base at ``pose`` with a fixed constraint of at most ``force`` [N]."""
        self.sim.set_pose(body, pose)
        position, orientation = pose_to_pb(pose)
        cid = pb.createConstraint(body.uid, -1, -1, -1, pb.JOINT_FIXED, [0, 0, 0],
                                  parentFramePosition=pose_to_pb(np.linalg.inv(body.inertial))[0],
                                  childFramePosition=position,
                                  parentFrameOrientation=pose_to_pb(np.linalg.inv(body.inertial))[1],
                                  childFrameOrientation=orientation, physicsClientId=self.c)
        pb.changeConstraint(cid, maxForce=force, physicsClientId=self.c)
        return cid

    def move_hold(self, cid: int, pose: np.ndarray, force: float) -> None:
        position, orientation = pose_to_pb(pose)
        pb.changeConstraint(cid, jointChildPivot=position, jointChildFrameOrientation=orientation, maxForce=force,
                            physicsClientId=self.c)

    def drive(self, body: Body, targets: dict[str, float], force: float) -> None:
        """Position-controlled finger motors, each limited to ``force`` [N or N m]."""
        for name, value in targets.items():
            pb.setJointMotorControl2(body.uid, body.joints[name], pb.POSITION_CONTROL, targetPosition=value,
                                     force=force, maxVelocity=FINGER_SPEED, physicsClientId=self.c)

    def set_friction(self, uid: int, friction: float) -> None:
        for link in range(-1, pb.getNumJoints(uid, physicsClientId=self.c)):
            pb.changeDynamics(uid, link, lateralFriction=friction, physicsClientId=self.c)

    def push(self, uid: int, force: np.ndarray) -> None:
        """A force [N] through the object's centre of mass, world frame, for one step."""
        position, _ = pb.getBasePositionAndOrientation(uid, physicsClientId=self.c)
        pb.applyExternalForce(uid, -1, list(force), list(position), pb.WORLD_FRAME, physicsClientId=self.c)

    def step(self, n: int = 1) -> None:
        for _ in range(n):
            pb.stepSimulation(physicsClientId=self.c)

    def overlap(self, body: Body, uid: int) -> float:
        """Deepest overlap [m] between a hand and the object now (0 if none)."""
        rows = pb.getClosestPoints(body.uid, uid, 0.0, physicsClientId=self.c)
        return max([0.0] + [-row[8] for row in rows])

    def touching_links(self, hand: Body, uid: int) -> set[int]:
        """Hand link indices in contact with the object now."""
        return {row[3] for row in pb.getContactPoints(hand.uid, uid, physicsClientId=self.c)}
