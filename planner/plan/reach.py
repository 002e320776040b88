"""Reachability: can an arm put the hand at a grasp, and at its pre-grasp,
without collision?

The scene: the robot base at a configurable pose, a table whose top is the
plane z = ``table_height`` in front of the robot, and the object resting on
it at a given pose. For a grasp (hand pose in the object frame), the hand
pose in the world is ``object_pose @ grasp_pose``; the arm's end-effector
target is that pose times the inverse of the hand's mount. IK is PyBullet's
damped least squares with seeded random restarts; a solution counts only if
it respects the joint limits, forward kinematics puts the end effector
within 1 mm and 0.5 degree of the target, and nothing collides: the arm
never touches table or object; the hand never touches the table; at the
grasp the hand may touch the object (that is the grasp) but not penetrate it
by more than 1 mm; at the pre-grasp (backed off along the approach, fingers
open) nothing touches.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from planner.geometry.frames import angle_between, rotation_from_rotvec
from planner.geometry.solid import PreparedObject
from planner.geometry.support import Support, upright
from planner.plan.tolerances import (
    ANGLE_TOL,
    IK_CONVERGED,
    IK_REFINEMENTS,
    JOINT_LIMIT_SLACK,
    MAX_PENETRATION,
    PARKING_DEPTH,
    PATH_ANGLE,
    PATH_STEPS,
    PATH_TOL,
    POSITION_TOL,
    PREGRASP_DISTANCE,
    TABLE_HALF,
    TABLE_REACH,
)
from planner.sim import Body, Sim
from planner.specs.hands import HandSpec
from planner.specs.up import DEFAULT_UP


@dataclass(frozen=True)
class ReachSettings:
    """Scene and solver settings (metres, radians)."""

    pregrasp_distance: float = PREGRASP_DISTANCE
    restarts: int = 4
    placements: int = 6  # object placements for the stored reachability score
    region_x: tuple[float, float] = (0.35, 0.65)  # placements, in the robot base frame
    region_y: tuple[float, float] = (-0.30, 0.30)
    table_height: float = 0.0  # table top, world z
    max_penetration: float = MAX_PENETRATION


#: Why a grasp is not reachable, in the order they are checked.
MISSES = ("the hand at the grasp would hit the table", "the open hand at the pre-grasp would hit the table",
          "no collision-free arm solution within the joint limits at the grasp",
          "no collision-free arm solution at the pre-grasp (backed off along the approach)",
          "the arm cannot back off along the approach: its pre-grasp solutions turn its joints another way")


@dataclass(frozen=True)
class ArmSolution:
    """Arm joint values [rad] by name, and how good the solution is."""

    joints: dict[str, float]
    position_error: float  # [m]
    angle_error: float  # [rad]
    manipulability: float  # sqrt(det(J J^T)) of the arm at this configuration


@dataclass(frozen=True)
class Reach:
    grasp: ArmSolution | None
    pregrasp: ArmSolution | None
    why: str = ""  # why not reachable: one of MISSES (empty when reachable)

    @property
    def reachable(self) -> bool:
        return self.grasp is not None and self.pregrasp is not None


@dataclass
class ReachScene:
    """Arm + hand + table + object, in one :class:`Sim`."""

    sim: Sim
    hand: HandSpec
    obj: PreparedObject
    settings: ReachSettings = field(default_factory=ReachSettings)
    robot_base: np.ndarray = field(default_factory=lambda: np.eye(4))

    def __post_init__(self) -> None:
        if self.hand.arm is None:
            from planner.errors import ConfigError

            raise ConfigError(f"hand '{self.hand.name}' names no [arm] in its hand.toml")
        arm = self.hand.arm
        self.arm: Body = self.sim.load_urdf(arm.urdf, fixed=True)
        self.sim.set_pose(self.arm, self.robot_base)
        self.ee_link = arm.ee_link
        self.mount_inv = np.linalg.inv(arm.mount)
        hand_in_arm = self.hand.root_link in self.arm.links
        self.hand_body: Body = self.arm if hand_in_arm else self.sim.load_urdf(self.hand.urdf, fixed=True)
        self.dofs = self.sim.movable_joints(self.arm)
        fingers = {j.name for j in self.hand.joints}
        self.arm_joints = [j for j in self.dofs if j not in fingers]
        limits = [self.sim.joint_limits(self.arm, j) for j in self.dofs]
        self.lower = [lo for lo, _ in limits]
        self.upper = [hi for _, hi in limits]
        self.rest = [0.5 * (lo + hi) for lo, hi in limits]
        hand_links = set(self.hand.links)
        self.arm_links = [n for n, i in self.arm.links.items() if n not in hand_links and
                          self.sim.has_collision(self.arm, n)]
        self.hand_links = [n for n in self.hand.links if self.sim.has_collision(self.hand_body, n)]
        top = self.settings.table_height
        table_pose = np.eye(4)
        table_pose[:3, 3] = (self.robot_base[0, 3] + TABLE_HALF[0] * TABLE_REACH, self.robot_base[1, 3],
                             top - TABLE_HALF[2])
        self.table = self.sim.add_box(TABLE_HALF, table_pose)
        self.object_body = self.sim.add_static_mesh(self.obj.mesh.vertices, self.obj.mesh.faces)
        self.object_pose = np.eye(4)
        self.object_hash = self.obj.mesh_hash
        # a free copy of the hand: checks the hand alone against the table
        # before any IK is spent on a grasp whose palm would go through it
        self.probe: Body = self.sim.load_urdf(self.hand.urdf, fixed=True)
        self._park_probe()

    def _park_probe(self) -> None:
        away = np.eye(4)
        away[:3, 3] = (0.0, 0.0, -PARKING_DEPTH)
        self.sim.set_pose(self.probe, away)

    def hand_hits_table(self, hand_pose: np.ndarray, fingers: dict[str, float]) -> bool:
        self.sim.set_pose(self.probe, hand_pose)
        self.sim.set_joints(self.probe, fingers)
        hit = any(self._gap(self.probe, link, self.table) <= 0 for link in self.hand_links)
        self._park_probe()
        return hit

    # -- scene ---------------------------------------------------------------
    def use_object(self, obj: PreparedObject) -> None:
        """Swap the object (the arm, hand and table stay loaded)."""
        if obj.mesh_hash != self.object_hash:
            self.sim.remove_body(self.object_body)
            self.object_body = self.sim.add_static_mesh(obj.mesh.vertices, obj.mesh.faces)
            self.object_hash = obj.mesh_hash
        self.obj = obj
        self.place_object(np.eye(4))

    def place_object(self, pose: np.ndarray) -> None:
        self.object_pose = pose
        self.sim.set_base_pose(self.object_body, pose)

    def resting_pose(self, x: float, y: float, yaw: float, support: Support | None = None) -> np.ndarray:
        """Object standing on the table (on its own up, ``PreparedObject.up``: its
        lowest point along it on the table top; with ``support``, on that table
        plane), turned by ``yaw``."""
        pose = np.eye(4)
        pose[:3, :3] = rotation_from_rotvec([0.0, 0.0, yaw])
        base = self.robot_base[:3, 3]
        if support is None and self.obj.spec.up != DEFAULT_UP:
            support = Support(self.obj.up, float((self.obj.mesh.vertices @ self.obj.up).min()))
        if support is None:  # its file's +z up: the frame as it is
            pose[:3, 3] = (base[0] + x, base[1] + y, self.settings.table_height - self.obj.mesh.bounds[0][2])
            return pose
        pose[:3, :3] = pose[:3, :3] @ upright(support.normal)
        pose[:3, 3] = (base[0] + x, base[1] + y, self.settings.table_height - support.height)
        return pose

    def placements(self, rng: np.random.Generator, support: Support | None = None) -> list[np.ndarray]:
        """Seeded object placements on the table (standing, or on ``support``)."""
        s = self.settings
        xs = rng.uniform(*s.region_x, s.placements)
        ys = rng.uniform(*s.region_y, s.placements)
        yaws = rng.uniform(-np.pi, np.pi, s.placements)
        return [self.resting_pose(x, y, yaw, support) for x, y, yaw in zip(xs, ys, yaws)]

    # -- checks ----------------------------------------------------------------
    def check(self, grasp_pose: np.ndarray, closed: dict[str, float], open_: dict[str, float],
              rng: np.random.Generator) -> Reach:
        """Grasp and pre-grasp IK at the current object placement; a mimic
        joint ``open_`` lacks follows its master (the antipodal sweep stores
        the driven joints of the opening it fitted)."""
        open_ = self.hand.posture(open_)
        world = self.object_pose @ grasp_pose
        pre = world.copy()
        pre[:3, 3] -= (world[:3, :3] @ self.hand.approach) * self.settings.pregrasp_distance
        if self.hand_hits_table(world, closed):
            return Reach(None, None, MISSES[0])
        if self.hand_hits_table(pre, open_):
            return Reach(None, None, MISSES[1])
        grasp = self.solve(world, closed, rng, grasp=True)
        if grasp is None:
            return Reach(None, None, MISSES[2])
        found: list[ArmSolution] = []  # pre-grasp solutions, straight or not

        def straight(solution: ArmSolution) -> bool:
            found.append(solution)
            return self._straight(grasp, solution, world, pre)  # type: ignore[arg-type]

        pregrasp = self.solve(pre, open_, rng, grasp=False, seed=grasp, accept=straight)
        if pregrasp is None:
            return Reach(grasp, None, MISSES[4] if found else MISSES[3])
        return Reach(grasp, pregrasp)

    def solve(self, hand_pose: np.ndarray, fingers: dict[str, float], rng: np.random.Generator, *, grasp: bool,
              seed: ArmSolution | None = None,
              accept: Callable[[ArmSolution], bool] | None = None) -> ArmSolution | None:
        """A verified, collision-free arm configuration putting the hand at
        ``hand_pose`` (and that ``accept`` takes, when given)."""
        target = hand_pose @ self.mount_inv
        for attempt in range(self.settings.restarts):
            if attempt == 0 and seed is not None:
                start = [seed.joints.get(j, r) for j, r in zip(self.dofs, self.rest)]
            elif attempt == 0:
                start = list(self.rest)
            else:
                start = list(rng.uniform(self.lower, self.upper))
            config = self._ik(start, target)
            solution = self._verify(config, fingers, target, grasp)
            if solution is not None and (accept is None or accept(solution)):
                return solution
        return None

    def _straight(self, grasp: ArmSolution, pregrasp: ArmSolution, grasp_pose: np.ndarray,
                  pre_pose: np.ndarray) -> bool:
        """Whether interpolating the arm's joints from ``grasp`` to
        ``pregrasp`` keeps the hand within PATH_TOL x the back-off distance
        (at least POSITION_TOL) of the straight line between the two hand
        poses (world) and within PATH_ANGLE of their orientation (:data:`~planner.plan.tolerances.
        PATH_STEPS` points)."""
        a, b = (grasp_pose @ self.mount_inv), (pre_pose @ self.mount_inv)
        # each end is verified only within POSITION_TOL: no tighter than that (a back-off of 0: no line at all)
        tolerance = max(PATH_TOL * self.settings.pregrasp_distance, POSITION_TOL)
        start = np.array([grasp.joints[j] for j in self.arm_joints])
        end = np.array([pregrasp.joints[j] for j in self.arm_joints])
        for t in np.linspace(0.0, 1.0, PATH_STEPS + 1)[1:-1]:
            self.sim.set_joints(self.arm, dict(zip(self.arm_joints, (1 - t) * start + t * end)))
            ee = self.sim.link_pose(self.arm, self.ee_link)
            off = ee[:3, 3] - a[:3, 3]
            line = b[:3, 3] - a[:3, 3]
            along = np.clip(off @ line / max(line @ line, 1e-18), 0.0, 1.0)
            if (np.linalg.norm(off - along * line) > tolerance
                    or angle_between(ee[:3, :3], a[:3, :3]) > PATH_ANGLE):
                return False
        return True

    def _ik(self, start: list[float], target: np.ndarray) -> dict[str, float]:
        """PyBullet's IK, re-run from its own answer until FK is within tolerance
        (one call often stops a few millimetres short)."""
        self.sim.set_joints(self.arm, dict(zip(self.dofs, start)))
        config: dict[str, float] = {}
        for attempt in range(IK_REFINEMENTS):
            if attempt == 0:  # null-space IK: a configuration inside the limits, near the rest pose
                values = self.sim.inverse_kinematics(self.arm, self.ee_link, target, self.lower, self.upper,
                                                     self.rest)
            else:  # then plain IK from there, which converges to the target
                values = self.sim.inverse_kinematics(self.arm, self.ee_link, target)
            config = {j: v for j, v in zip(self.dofs, values) if j in self.arm_joints}
            self.sim.set_joints(self.arm, config)
            ee = self.sim.link_pose(self.arm, self.ee_link)
            if (np.linalg.norm(ee[:3, 3] - target[:3, 3]) <= POSITION_TOL * IK_CONVERGED
                    and angle_between(ee[:3, :3], target[:3, :3]) <= ANGLE_TOL * IK_CONVERGED):
                break
        return config

    def _verify(self, config: dict[str, float], fingers: dict[str, float], target: np.ndarray,
                grasp: bool) -> ArmSolution | None:
        for j, v in config.items():
            lo, hi = self.lower[self.dofs.index(j)], self.upper[self.dofs.index(j)]
            if not lo - JOINT_LIMIT_SLACK <= v <= hi + JOINT_LIMIT_SLACK:
                return None
        self.sim.set_joints(self.arm, config)
        ee = self.sim.link_pose(self.arm, self.ee_link)
        pos_err = float(np.linalg.norm(ee[:3, 3] - target[:3, 3]))
        ang_err = angle_between(ee[:3, :3], target[:3, :3])
        if pos_err > POSITION_TOL or ang_err > ANGLE_TOL:
            return None
        if self.hand_body is not self.arm:
            self.sim.set_pose(self.hand_body, ee @ self.hand.arm.mount)  # type: ignore[union-attr]
        self.sim.set_joints(self.hand_body, fingers)
        if self._collides(grasp):
            return None
        dof_values = self.sim.joint_values(self.arm, self.dofs)
        jac = self.sim.jacobian(self.arm, self.ee_link, dof_values)
        cols = [self.dofs.index(j) for j in self.arm_joints]
        j_arm = jac[:, cols]
        manip = float(np.sqrt(max(np.linalg.det(j_arm @ j_arm.T), 0.0)))
        return ArmSolution({j: float(v) for j, v in config.items()}, pos_err, ang_err, manip)

    def _gap(self, body: Body, link: str, other: int, reach: float = 0.0) -> float:
        pairs = self.sim.closest(body.uid, other, reach - self.hand.distance_offset, body.links[link])
        return pairs.min_distance + self.hand.distance_offset

    def _collides(self, grasp: bool) -> bool:
        for link in self.arm_links:
            # the base link is bolted to the table: only the object counts for it
            on_table = self.arm.links[link] >= 0 and self._gap(self.arm, link, self.table) <= 0
            if on_table or self._gap(self.arm, link, self.object_body) <= 0:
                return True
        floor = -self.settings.max_penetration if grasp else 0.0
        for link in self.hand_links:
            if self._gap(self.hand_body, link, self.table) <= 0:
                return True
            if self._gap(self.hand_body, link, self.object_body) <= floor:
                return True
        return False


#: One reachability scene per (hand, settings) in each process: loading the
#: arm, the hand and the probe costs ~0.3 s of CPU, which every unit of work
#: paid again before; only the object changes between units.
_SCENES: dict[tuple[str, ReachSettings], ReachScene] = {}


def reach_scene(hand: HandSpec, obj: PreparedObject, settings: ReachSettings) -> ReachScene:
    """This process's scene for ``hand`` and ``settings``, holding ``obj``
    (robot base at the origin). It lives as long as the process."""
    key = (hand.name, settings)
    scene = _SCENES.get(key)
    if scene is None or scene.hand is not hand:
        scene = _SCENES[key] = ReachScene(Sim(), hand, obj, settings)
    scene.use_object(obj)
    return scene
