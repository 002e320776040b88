"""Dynamic PyBullet worlds for shake trials: free objects (PyBullet
primitives or convex parts), fixed hands with rigid contacts, finger motors,
gear couplings, joint limits and a gravity vector that stands for any load.
Part of the PyBullet adapter (only ``planner.sim`` imports pybullet).

Contact friction: Bullet combines the two bodies' lateral frictions as their
product and spinning frictions as ``s_a mu_b + s_b mu_a`` (bullet3
``btManifoldResult``). Hand links get lateral friction 1 and objects spinning
friction 0, so a contact's friction is exactly the object's mu and a pad's
moment about the normal is at most ``mu x spinning x normal force``.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from planner import assets
from planner.geometry.quaternion import quaternion_xyzw
from planner.sim import Body, Sim, pb, pb_to_pose, pose_to_pb

#: [kg m^2] smallest principal moment given to PyBullet: a flat part's eigen
#: solver may return 0 (or -1e-20), which PyBullet rejects.
MIN_MOMENT = 1e-9
#: [m] overlaps shallower than this are resolved by split impulses (position
#: only, no added velocity): a decomposed object starting slightly inside the
#: hand must not be shot away.
SPLIT_IMPULSE_DEPTH = 0.001
#: PyBullet collision filter groups are bit masks of this many usable bits:
#: the most trials one world can keep apart at the same place.
FILTER_BITS = 30
#: Decimals kept of every length [m], angle [rad] and quaternion component a
#: dynamic world is given. A trial is chaotic (contacts make and break), so
#: the last bits by which numpy's results differ between BLAS kernels (AVX2
#: and AVX-512 builds of the same expression) grow into other verdicts and
#: settled epsilons; inputs rounded to 1e-10 are the same on every machine
#: (unless a value falls within an ulp of a rounding boundary, ~1e-6 odds).
INPUT_DECIMALS = 10
#: Significant digits kept of the principal moments of inertia.
MOMENT_DIGITS = 10
#: Principal moments within this fraction of the largest are equal (a
#: cylinder's two, a sphere's three): their axes are chosen from the object
#: axes, not left to the eigen solver, which may return any basis of a
#: degenerate eigenspace.
EQUAL_MOMENTS = 1e-9
#: URDF ``<contact>`` blocks (PyBullet's soft contact stiffness/damping,
#: spinning and rolling friction): removed, the trial sets contacts itself.
_CONTACT_BLOCK = re.compile(r"<contact>.*?</contact>", re.S)
#: This process's reusable PyBullet client, by process id (a forked child
#: must not use its parent's).
_CLIENTS: dict[int, Sim] = {}


@dataclass(frozen=True)
class Shape:
    """How a free object collides: a PyBullet primitive (``box`` with
    ``dims`` = extents [m], ``sphere`` (radius), ``cylinder`` (radius, height
    along z), centred on the object frame) or ``parts``: convex OBJ files in
    the object frame (:func:`part_file`)."""

    kind: str
    dims: tuple[float, ...] = ()
    files: tuple[str, ...] = ()


def part_file(vertices: np.ndarray, faces: np.ndarray) -> str:
    """A convex part as a small OBJ file in the cache (PyBullet's compound
    shapes take files, not vertex lists); named by its content."""
    v, f = np.asarray(vertices, float), np.asarray(faces, int)
    path = assets.cache_dir("parts") / f"{assets.sha256_bytes(v.tobytes() + f.tobytes())[:20]}.obj"
    if not path.is_file():
        text = "".join(f"v {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in v)
        text += "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in f)
        assets.atomic_write(path, text.encode())
    return str(path)


#: The most children PyBullet 3.2.7 builds from one createCollisionShapeArray
#: (MAX_COMPOUND_COLLISION_SHAPES of its command API): it drops the rest without
#: a word (until 2026-12-06 a mug's 32 CoACD parts were 16 in the PyBullet trial
#: and the settle).
MAX_SHAPE_ARRAY = 16


def parts_file(files: tuple[str, ...]) -> str:
    """The convex parts of :func:`part_file` in one OBJ file, each part an
    object (``o``) of its own, in the cache (named by its content): PyBullet
    reads such a file as a compound of one convex hull per object."""
    text, offset = [], 0
    for i, name in enumerate(files):
        lines = Path(name).read_text().splitlines()
        vertices = [line for line in lines if line.startswith("v ")]
        text.append(f"o part{i}\n" + "".join(line + "\n" for line in vertices))
        for line in lines:
            if line.startswith("f "):
                a, b, c = (int(k) + offset for k in line.split()[1:4])
                text.append(f"f {a} {b} {c}\n")
        offset += len(vertices)
    data = "".join(text).encode()
    path = assets.cache_dir("parts") / f"all-{assets.sha256_bytes(data)[:20]}.obj"
    if not path.is_file():
        assets.atomic_write(path, data)
    return str(path)


def rigid_urdf(urdf: Path) -> Path:
    """The URDF without its ``<contact>`` blocks (the Panda's fingers carry a
    soft contact, stiffness 3e4 N/m, that lets them sink ~1 cm into the
    object, and spinning friction 0.1 m); a cached copy, or the file itself."""
    text = urdf.read_text()
    cleaned = _CONTACT_BLOCK.sub("", text)
    if cleaned == text:
        return urdf
    path = assets.cache_dir("hands") / f"rigid-{assets.sha256_bytes(cleaned.encode())[:16]}.urdf"
    if not path.is_file():
        assets.atomic_write(path, cleaned.encode())
    return path


@contextmanager
def fresh_world(dt: float, solver_iterations: int) -> Iterator[Dynamics]:
    """An empty dynamic world on this process's reusable PyBullet client:
    connecting costs ~30 ms of CPU (more than a whole Panda trial), while
    ``resetSimulation`` rebuilds the world from scratch in ~1 ms, so a trial
    gives the same numbers whatever ran before it."""
    sim = _CLIENTS.get(os.getpid())
    if sim is None:
        sim = _CLIENTS[os.getpid()] = Sim()
    pb.resetSimulation(physicsClientId=sim.client)
    try:
        yield Dynamics(sim, dt, solver_iterations)
    finally:
        pb.resetSimulation(physicsClientId=sim.client)


class Dynamics:
    """Dynamic operations on one :class:`Sim` (time step ``dt`` [s], no gravity
    until :meth:`set_gravity`)."""

    def __init__(self, sim: Sim, dt: float = 1.0 / 480.0, solver_iterations: int = 50) -> None:
        self.sim = sim
        self.c = sim.client
        self.dt = dt
        # split impulses: resolving an overlap must not add velocity; deterministic
        # pair order and islands solved one by one: a trial's result does not depend on
        # what else is in the world's broadphase
        pb.setPhysicsEngineParameter(fixedTimeStep=dt, numSolverIterations=solver_iterations, useSplitImpulse=1,
                                     splitImpulsePenetrationThreshold=-SPLIT_IMPULSE_DEPTH,
                                     deterministicOverlappingPairs=1, minimumSolverIslandSize=1,
                                     physicsClientId=self.c)
        pb.setGravity(0, 0, 0, physicsClientId=self.c)
        self._constraints: set[int] = set()  # made by gear(), not yet released
        self._limits: dict[tuple[int, int], tuple[float, float]] = {}  # (body, joint) -> limits before set_limits
        self._shapes: dict[Shape, int] = {}  # collision shapes made in this world, shared by its objects

    # -- bodies ------------------------------------------------------------------
    def add_object(self, shape: Shape, mass: float, com: np.ndarray, inertia: np.ndarray, friction: float,
                   pose: np.ndarray) -> int:
        """A free rigid body of ``mass`` [kg] with its centre of mass ``com``
        (3,) [m] and ``inertia`` (3, 3) [kg m^2] about it (object frame),
        lateral friction ``friction``, its object frame placed at ``pose``."""
        moments, frame = principal_inertia(inertia)
        uid = pb.createMultiBody(mass, self._collision_shape(shape), -1, basePosition=[0, 0, 0],
                                 baseInertialFramePosition=rounded(com),
                                 baseInertialFrameOrientation=frame, physicsClientId=self.c)
        pb.changeDynamics(uid, -1, localInertiaDiagonal=moments, lateralFriction=friction,
                          spinningFriction=0.0, rollingFriction=0.0, linearDamping=0.0, angularDamping=0.0,
                          physicsClientId=self.c)
        self.set_object_pose(uid, pose)
        return uid

    def _collision_shape(self, shape: Shape) -> int:
        """PyBullet's collision shape of ``shape``, made once per world (a
        mug's 24 parts take ~1 ms to read, and objects removed leave their
        shape in the world for the next)."""
        if shape not in self._shapes:
            self._shapes[shape] = self._new_collision_shape(shape)
        return self._shapes[shape]

    def _new_collision_shape(self, shape: Shape) -> int:
        c = self.c
        if shape.kind == "box":
            return pb.createCollisionShape(pb.GEOM_BOX, halfExtents=[d / 2 for d in shape.dims], physicsClientId=c)
        if shape.kind == "sphere":
            return pb.createCollisionShape(pb.GEOM_SPHERE, radius=shape.dims[0], physicsClientId=c)
        if shape.kind == "cylinder":
            return pb.createCollisionShape(pb.GEOM_CYLINDER, radius=shape.dims[0], height=shape.dims[1],
                                           physicsClientId=c)
        # no `flags` here: PyBullet 3.2.7's createCollisionShapeArray corrupts memory when
        # given a flags list (a segfault with 24 parts; with one part, later closest-point
        # queries silently return nothing)
        if len(shape.files) <= MAX_SHAPE_ARRAY:
            return pb.createCollisionShapeArray([pb.GEOM_MESH] * len(shape.files), fileNames=list(shape.files),
                                                physicsClientId=c)
        # more parts than an array keeps: one OBJ file with each part an object of its own, which PyBullet
        # reads as a compound of their convex hulls (every part)
        return pb.createCollisionShape(pb.GEOM_MESH, fileName=parts_file(shape.files), physicsClientId=c)

    def add_hand(self, urdf: Path, inertia: Mapping[str, Sequence[float]] | None = None) -> Body:
        """The hand, rigid contacts (:func:`rigid_urdf`), its base fixed at the
        world origin: the world frame is the hand frame. No visual shapes: a
        trial is never drawn. PyBullet gives each link the URDF's mass and centre of mass and the moments of
        inertia of its collision shapes (not the URDF's); ``inertia`` {link: (3,) [kg m^2] principal moments}
        replaces those of the links it names."""
        body = self.sim.load_urdf(rigid_urdf(urdf), fixed=True, visual=False)
        self.sim.set_pose(body, np.eye(4))
        for link, moments in (inertia or {}).items():
            pb.changeDynamics(body.uid, body.links[link], localInertiaDiagonal=list(moments), physicsClientId=self.c)
        return body

    def set_contact(self, uid: int, link: int, spinning: float) -> None:
        """A hand link: lateral friction 1 (the contact's is then the object's),
        ``spinning`` [m] torsional friction, friction anchors (static friction
        does not creep), no damping."""
        pb.changeDynamics(uid, link, lateralFriction=1.0, spinningFriction=spinning, rollingFriction=0.0,
                          frictionAnchor=1, linearDamping=0.0, angularDamping=0.0, physicsClientId=self.c)

    def keep_apart(self, uids: list[int], bit: int) -> None:
        """Bodies that collide only with bodies of the same filter ``bit`` (< FILTER_BITS)."""
        mask = 1 << bit
        for uid in uids:
            for link in range(-1, pb.getNumJoints(uid, physicsClientId=self.c)):
                pb.setCollisionFilterGroupMask(uid, link, mask, mask, physicsClientId=self.c)

    def remove(self, uid: int) -> None:
        pb.removeBody(uid, physicsClientId=self.c)

    def set_object_pose(self, uid: int, pose: np.ndarray) -> None:
        """Place the object *frame* at ``pose`` (PyBullet places the inertial frame)."""
        info = pb.getDynamicsInfo(uid, -1, physicsClientId=self.c)
        position, orientation = pose_to_pb(pose @ pb_to_pose(info[3], info[4]))
        pb.resetBasePositionAndOrientation(uid, rounded(position), rounded(orientation), physicsClientId=self.c)
        pb.resetBaseVelocity(uid, [0, 0, 0], [0, 0, 0], physicsClientId=self.c)

    def set_joints(self, body: Body, values: dict[str, float]) -> None:
        """Joint values [rad or m], rounded to :data:`INPUT_DECIMALS`."""
        self.sim.set_joints(body, {name: round(float(v), INPUT_DECIMALS) for name, v in values.items()})

    # -- fingers -------------------------------------------------------------------
    def velocity_motor(self, body: Body, joint: str, velocity: float, force: float) -> None:
        """Drive ``joint`` at ``velocity`` [m/s or rad/s] with at most ``force``
        [N or N m]: once blocked, it pushes with exactly ``force``."""
        pb.setJointMotorControl2(body.uid, body.joints[joint], pb.VELOCITY_CONTROL, targetVelocity=velocity,
                                 force=force, physicsClientId=self.c)

    def position_motor(self, body: Body, joint: str, target: float, force: float) -> None:
        pb.setJointMotorControl2(body.uid, body.joints[joint], pb.POSITION_CONTROL, targetPosition=target,
                                 force=force, physicsClientId=self.c)

    def gear(self, body: Body, master: str, mimic: str, multiplier: float, max_force: float, erp: float) -> int:
        """Keep ``q[mimic] = multiplier * q[master]`` (a URDF <mimic>, which
        PyBullet's loader ignores). PyBullet's gear constraint keeps
        ``q_parent + ratio * q_child = 0`` (measured), hence ratio -1/multiplier."""
        cid = pb.createConstraint(body.uid, body.joints[master], body.uid, body.joints[mimic], pb.JOINT_GEAR,
                                  [1, 0, 0], [0, 0, 0], [0, 0, 0], physicsClientId=self.c)
        pb.changeConstraint(cid, gearRatio=-1.0 / multiplier, maxForce=max_force, erp=erp, physicsClientId=self.c)
        self._constraints.add(cid)
        return cid

    def release(self, cid: int) -> None:
        """Remove a constraint (a gear that has broken away)."""
        pb.removeConstraint(cid, physicsClientId=self.c)
        self._constraints.discard(cid)

    def set_limits(self, body: Body, joint: str, lower: float, upper: float) -> None:
        index = body.joints[joint]
        if (body.uid, index) not in self._limits:
            info = pb.getJointInfo(body.uid, index, physicsClientId=self.c)
            self._limits[(body.uid, index)] = (info[8], info[9])
        pb.changeDynamics(body.uid, index, jointLowerLimit=lower, jointUpperLimit=upper, physicsClientId=self.c)

    # -- one hand for many grasps ------------------------------------------------------
    def save(self) -> int:
        """PyBullet's record of the world now (every body's pose and velocities, contacts): see :meth:`restore`."""
        return pb.saveState(physicsClientId=self.c)

    def restore(self, state: int) -> None:
        """Back to the record ``state`` of :meth:`save` (made with the same bodies in the world)."""
        pb.restoreState(state, physicsClientId=self.c)

    def park(self, uid: int, pose: np.ndarray) -> None:
        """Move body ``uid`` to ``pose`` (4, 4), at rest, where it touches nothing, and forget its contacts there:
        the collision pass drops its pairs and their contact points, which :meth:`restore` keeps (a body that
        stays in the world from one trial to the next would start the next with the last one's contacts)."""
        self.set_object_pose(uid, pose)
        pb.performCollisionDetection(physicsClientId=self.c)

    def undo_fingers(self) -> None:
        """Remove the gears :meth:`gear` made that are still there and put
        back the joint limits :meth:`set_limits` changed: with the motors
        set again and the poses restored (:meth:`restore`), the hand is as
        loaded."""
        for cid in sorted(self._constraints):
            pb.removeConstraint(cid, physicsClientId=self.c)
        self._constraints.clear()
        for (uid, index), (lower, upper) in self._limits.items():
            pb.changeDynamics(uid, index, jointLowerLimit=lower, jointUpperLimit=upper, physicsClientId=self.c)
        self._limits.clear()

    def joint_position(self, body: Body, joint: str) -> float:
        return float(pb.getJointState(body.uid, body.joints[joint], physicsClientId=self.c)[0])

    # -- running and reading ----------------------------------------------------------
    def set_gravity(self, g: np.ndarray) -> None:
        """(3,) [m/s^2] in the world (= hand) frame."""
        pb.setGravity(*map(float, g), physicsClientId=self.c)

    def step(self, n: int = 1) -> None:
        for _ in range(n):
            pb.stepSimulation(physicsClientId=self.c)

    def object_pose(self, uid: int) -> np.ndarray:
        """(4, 4) the object frame in the world."""
        info = pb.getDynamicsInfo(uid, -1, physicsClientId=self.c)
        position, orientation = pb.getBasePositionAndOrientation(uid, physicsClientId=self.c)
        return pb_to_pose(position, orientation) @ np.linalg.inv(pb_to_pose(info[3], info[4]))

    def centre_of_mass(self, uid: int) -> np.ndarray:
        """(3,) [m] the object's centre of mass in the world."""
        return np.asarray(pb.getBasePositionAndOrientation(uid, physicsClientId=self.c)[0], float)

    def overlap(self, body: Body, uid: int) -> float:
        """Deepest overlap [m] PyBullet reports between a hand and an object now
        (0 if none); collision margins included (the caller corrects)."""
        rows = pb.getClosestPoints(body.uid, uid, 0.0, physicsClientId=self.c)
        return max([0.0] + [-row[8] for row in rows])

    def touching_links(self, body: Body, uid: int) -> set[int]:
        """Hand link indices in contact with the object now."""
        return {row[3] for row in pb.getContactPoints(body.uid, uid, physicsClientId=self.c)}

    def contact_points(self, body: Body, uid: int) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
        """The hand-object contacts now, object frame: points (n, 3) on the
        object [m], unit normals (n, 3) into the object, and each one's hand link."""
        names = {index: name for name, index in body.links.items()}
        rows = [row for row in pb.getContactPoints(body.uid, uid, physicsClientId=self.c) if row[3] in names]
        if not rows:
            return np.zeros((0, 3)), np.zeros((0, 3)), ()
        world_to_object = np.linalg.inv(self.object_pose(uid))
        rot, shift = world_to_object[:3, :3], world_to_object[:3, 3]
        points = np.array([row[6] for row in rows], float) @ rot.T + shift
        normals = -np.array([row[7] for row in rows], float) @ rot.T  # PyBullet's normal on B points out of B
        return points, normals, tuple(names[row[3]] for row in rows)


def rounded(values: np.ndarray | list[float] | tuple[float, ...]) -> list[float]:
    """Floats rounded to :data:`INPUT_DECIMALS` (see there: why)."""
    return [round(float(v), INPUT_DECIMALS) + 0.0 for v in values]


def principal_inertia(inertia: np.ndarray) -> tuple[list[float], list[float]]:
    """(3 principal moments [kg m^2], ascending, at least MIN_MOMENT; the
    quaternion x-y-z-w of their right-handed frame in the object frame) of a
    symmetric (3, 3) inertia tensor, the same on every machine: each axis's
    sign fixed (largest component positive), the axes of equal moments taken
    from the object axes (:data:`EQUAL_MOMENTS`), everything rounded."""
    values, axes = np.linalg.eigh(np.asarray(inertia, float))
    scale = max(float(np.abs(values).max()), MIN_MOMENT)
    equal = [abs(float(values[i + 1] - values[i])) <= EQUAL_MOMENTS * scale for i in range(2)]
    if all(equal):
        axes = np.eye(3)
    elif any(equal):
        single = 2 if equal[0] else 0  # the axis of the moment that differs
        axis = _signed(axes[:, single])
        plane = np.eye(3) - np.outer(axis, axis)
        first = _signed(plane[:, int(np.argmax(np.linalg.norm(plane, axis=0)))])
        pair = [first / np.linalg.norm(first), np.cross(axis, first / np.linalg.norm(first))]
        axes = np.column_stack([axis, *pair] if single == 0 else [*pair, axis])
    else:
        axes = np.column_stack([_signed(axes[:, i]) for i in range(3)])
    if np.linalg.det(axes) < 0:
        axes[:, 2] *= -1
    moments = [float(f"{max(float(v), MIN_MOMENT):.{MOMENT_DIGITS}g}") for v in values]
    return moments, rounded(quaternion_xyzw(axes))


def _signed(v: np.ndarray) -> np.ndarray:
    """``v`` with its largest-magnitude component made positive."""
    return v if v[int(np.argmax(np.abs(v)))] >= 0 else -v
