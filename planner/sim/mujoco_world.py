"""The MuJoCo adapter: with :mod:`planner.sim.mujoco_mjcf` (the model's
text), the only module that imports mujoco.

It compiles one world from a hand and a free object and offers what a
dynamic trial needs: placing bodies, driving finger joints, coupling and
uncoupling mimic joints, moving the hand, stepping, reading contacts, and
the clearance of the moving fingers from the object (how far they may close
in free space before they could touch it). The protocol that uses it is
elsewhere (:mod:`planner.validation.mujoco_trial`).

The world frame is the object's frame at rest (the object starts at the
identity); the hand's root link is a free body welded to a mocap body, so a
trial moves the hand by moving the mocap target and the contacts see the
hand's real velocity. Poses are 4x4 homogeneous matrices [m]; MuJoCo's
quaternions (w, x, y, z) never leave this module.

Every finger joint has a position actuator whose gain and force range the
trial sets (:meth:`World.drive`); the hand's geoms have priority in a
contact with the object, so the trial sets the contact's friction on the
hand alone (:meth:`World.set_friction`): sliding ``mu``, and on soft links
torsional ``mu x torsion_radius``.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from functools import partial

import mujoco
import numpy as np

from planner.errors import SimulationError
from planner.geometry.frames import rows_cross
from planner.sim.mujoco_mjcf import HAND_BASE, HAND_BITS, OBJECT, TARGET, Builder, Solid, quats
from planner.specs.hands import HandSpec
from planner.validation.mujoco_settings import Engine

__all__ = ["OBJECT", "TARGET", "VERSION", "Engine", "Solid", "World", "build"]

#: The MuJoCo release the trials run on (stored with each trial's settings).
VERSION: str = mujoco.__version__

log = logging.getLogger(__name__)
# MuJoCo's warnings (a diverged state it resets, a full contact buffer) go to the log, not to stdout and a
# MUJOCO_LOG.TXT in the user's working directory; each world still counts them (World.diverged).
mujoco.set_mju_user_warning(lambda message: log.warning("MuJoCo: %s", message))

#: MuJoCo's warnings of a diverged state (each followed by a reset of the state).
_DIVERGED = (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL, mujoco.mjtWarning.mjWARN_BADQACC)


#: (4, 4) the identity, copied for a pose (np.eye's call cost more than the copy, read ~10 times a trial)
_EYE = np.eye(4)


def _quat(rotation: np.ndarray) -> np.ndarray:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(rotation, float).ravel())
    return q


def build(hand: HandSpec, solid: Solid, engine: Engine | None = None) -> World:
    """A compiled world of ``hand`` and ``solid`` (MuJoCo's compile errors as SimulationError)."""
    builder = Builder(hand)
    engine = engine or Engine()
    xml = builder.xml(solid, engine)
    try:
        model = mujoco.MjModel.from_xml_string(xml)
    except ValueError as exc:
        raise SimulationError(f"MuJoCo cannot build hand '{hand.name}' with this object: {exc}") from exc
    # the model's text (mujoco_mjcf) writes the elliptic cone every trial ran with until 2026-12-07; another is set here
    model.opt.cone = mujoco.mjtCone.mjCONE_PYRAMIDAL if engine.cone == "pyramidal" else mujoco.mjtCone.mjCONE_ELLIPTIC
    return World(hand, model, engine)


class World:
    """One compiled MuJoCo model of a hand and an object, and its state."""

    def __init__(self, hand: HandSpec, model: mujoco.MjModel, engine: Engine | None = None) -> None:
        self.hand = hand
        engine = engine or Engine()
        #: the solref of a limit the trial sets (set_limits): as stiff as a contact, not MuJoCo's soft default
        self._held = (engine.contact_time, engine.contact_damping)
        self.model = model
        self.data = mujoco.MjData(model)
        m = model
        self._name = lambda kind, i: mujoco.mj_id2name(m, kind, i)
        self.object_body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, OBJECT)
        self._target = int(m.body_mocapid[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, TARGET)])
        self._base = m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, HAND_BASE)]
        self._base_dof = m.jnt_dofadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, HAND_BASE)]
        obj_joint = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, OBJECT)
        self._object_q, self._object_v = m.jnt_qposadr[obj_joint], m.jnt_dofadr[obj_joint]
        self.joints = {j.name: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j.name) for j in hand.joints}
        self.motors = {j.name: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, f"motor:{j.name}")
                       for j in hand.joints}
        self.gears = {j.name: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_EQUALITY, f"gear:{j.name}")
                      for j in hand.joints if j.mimic is not None}
        #: hand geom index -> its link's name; the object's geoms
        self.hand_geoms = {g: self._name(mujoco.mjtObj.mjOBJ_BODY, int(m.geom_bodyid[g]))
                           for g in range(m.ngeom) if m.geom_contype[g] == HAND_BITS}
        self.object_geoms = frozenset(g for g in range(m.ngeom) if int(m.geom_bodyid[g]) == self.object_body)
        self._ranges, self._solrefs = m.jnt_range.copy(), m.jnt_solref.copy()
        #: views of the arrays read or written every step of closing (each attribute read makes a new view)
        self._range, self._solref, self._qpos = m.jnt_range, m.jnt_solref, self.data.qpos
        self._qpos_of = {name: int(m.jnt_qposadr[j]) for name, j in self.joints.items()}
        self._force = np.zeros(6)
        self._hand_body = int(m.jnt_bodyid[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, HAND_BASE)])
        #: hand geom -> the finger joints (ids) between it and the hand's root
        chains = [(g, j) for g in self.hand_geoms for j in self._chain(int(m.geom_bodyid[g]))]
        #: every (hand geom, finger joint that moves it) pair: geom ids, joint ids, whether the joint slides
        self._links = (np.array([g for g, _ in chains], int), np.array([j for _, j in chains], int),
                       np.array([m.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE for _, j in chains], bool))
        self._margins, self._body_margins = m.geom_margin.copy(), m.body_margin.copy()
        #: the warnings of a diverged state, as indices of MuJoCo's warning counters (read at once)
        self._diverging = np.array([int(w) for w in _DIVERGED])

    # -- placing -------------------------------------------------------------------
    def reset(self, hand_pose: np.ndarray, joints: Mapping[str, float], object_pose: np.ndarray | None = None) -> None:
        """A fresh state: the hand's root frame (and its weld target) at
        ``hand_pose``, finger ``joints`` [rad or m], the object frame at
        ``object_pose`` (default: the identity), everything at rest, motors
        idle, gears engaged, joint limits as built, no gravity."""
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        m.jnt_range[:], m.jnt_solref[:] = self._ranges, self._solrefs
        m.opt.gravity[:] = 0.0
        for i in range(m.nu):
            self._set_motor(i, 0.0, 0.0, 0.0, 0.0, 0.0)
        for eq in self.gears.values():
            d.eq_active[eq] = 1
        self._place(self._base, hand_pose)
        self.move_hand(hand_pose)
        self._place(self._object_q, np.eye(4) if object_pose is None else object_pose)
        for name, value in joints.items():
            d.qpos[m.jnt_qposadr[self.joints[name]]] = value
        mujoco.mj_forward(m, d)

    def _place(self, address: int, pose: np.ndarray) -> None:
        self.data.qpos[address:address + 3] = pose[:3, 3]
        self.data.qpos[address + 3:address + 7] = _quat(pose[:3, :3])

    def move_hand(self, pose: np.ndarray) -> None:
        """Set the hand's weld target to ``pose`` (the hand follows it)."""
        self.data.mocap_pos[self._target] = pose[:3, 3]
        self.data.mocap_quat[self._target] = _quat(pose[:3, :3])

    @staticmethod
    def targets(poses: np.ndarray) -> np.ndarray:
        """(n, 7) the weld targets (position, MuJoCo's quaternion) of (n, 4, 4) hand poses, for
        :meth:`follow` (a path converted once, not a quaternion per step)."""
        poses = np.asarray(poses, float).reshape(-1, 4, 4)
        return np.concatenate([poses[:, :3, 3], quats(poses[:, :3, :3])], axis=1)

    def follow(self, target: np.ndarray) -> None:
        """Set the hand's weld target to a (7,) row of :meth:`targets`."""
        self.data.mocap_pos[self._target] = target[:3]
        self.data.mocap_quat[self._target] = target[3:]

    def follow_path(self, targets: np.ndarray) -> None:
        """One step per row of ``targets`` (:meth:`targets`), the hand's weld target set to the row first
        (:meth:`follow` then :meth:`step`, without a Python call per step)."""
        m, d = self.model, self.data
        position, turn, step = d.mocap_pos[self._target], d.mocap_quat[self._target], mujoco.mj_step
        for xyz, q in zip(targets[:, :3], targets[:, 3:]):
            position[:] = xyz
            turn[:] = q
            step(m, d)

    def set_fingers(self, positions: Mapping[str, float], speeds: Mapping[str, float], probe: bool = False) -> None:
        """Finger joints at ``positions`` [rad or m] moving at ``speeds`` [rad/s or m/s] (joints not named
        keep theirs), hand and object as they are; everything recomputed, or (``probe``) only the bodies'
        poses, enough for :meth:`clearance` (then set the fingers again before stepping)."""
        m, d = self.model, self.data
        for name, value in positions.items():
            d.qpos[m.jnt_qposadr[self.joints[name]]] = value
        for name, value in speeds.items():
            d.qvel[m.jnt_dofadr[self.joints[name]]] = value
        (mujoco.mj_kinematics if probe else mujoco.mj_forward)(m, d)

    # -- clearance -----------------------------------------------------------------
    def _chain(self, body: int) -> tuple[int, ...]:
        """The finger joints (ids) that move ``body``, from it up to the hand's root."""
        m, out = self.model, []
        while body > 0 and body != self._hand_body:
            out += [j for j in range(m.body_jntadr[body], m.body_jntadr[body] + m.body_jntnum[body])
                    if int(m.jnt_type[j]) in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))]
            body = int(m.body_parentid[body])
        return tuple(out)

    def clearance(self, speeds: Mapping[str, float], reach: float) -> tuple[float, float]:
        """(gap [m], speed [m/s]) of the hand's geoms that finger joints moving at ``speeds`` [rad/s or
        m/s] move, at the configuration :meth:`set_fingers` left: the least distance from any of them to
        the object (``reach`` if none is nearer), and a bound on how fast any point of them moves (each
        joint between a geom and the hand's root adds its speed times the farthest the geom reaches from
        its axis: the distance of the geom's centre plus its bounding radius; a slide adds its speed).
        Over a closing time ``(gap - margin) / speed`` no point of them comes nearer to the object than
        ``margin``, to first order (the reach from an axis changes as the joints below it turn).
        Contacts are searched with the moving geoms' margin at ``reach`` (the contacts read until the
        next :meth:`set_fingers` or :meth:`step` are those)."""
        m, d = self.model, self.data
        rate = np.zeros(m.njnt)
        for name, v in speeds.items():
            rate[self.joints[name]] = abs(v)
        g, j, slide = self._links
        arm = np.where(slide, 1.0, np.linalg.norm(rows_cross(d.geom_xpos[g] - d.xanchor[j], d.xaxis[j]), axis=1)
                       + m.geom_rbound[g])
        bound = np.bincount(g, rate[j] * arm, minlength=m.ngeom)
        moving = {int(i): float(bound[i]) for i in np.flatnonzero(bound > 0.0)}
        if not moving:
            return reach, 0.0
        try:
            m.geom_margin[list(moving)] = reach
            # and their bodies': the bounding-volume tree around a body's geoms is pruned at the bodies' margins
            # (compiled: 0), so a part within reach whose box the moving geom did not meet went unseen (the
            # gap read too large: up to 4.7 cm of 5 on the Barrett, 17% of its probes)
            m.body_margin[m.geom_bodyid[list(moving)]] = reach
            mujoco.mj_collision(m, d)
            con, obj = d.contact, self.object_geoms  # read as arrays: no Python object per contact
            gaps = [dist for g1, g2, dist in zip(con.geom1.tolist(), con.geom2.tolist(), con.dist.tolist())
                    if (g1 in moving and g2 in obj) or (g2 in moving and g1 in obj)]
        finally:
            m.geom_margin[:], m.body_margin[:] = self._margins, self._body_margins
        return min([reach, *gaps]), max(moving.values())

    def set_friction(self, mu: float, torsion: Mapping[str, float]) -> None:
        """Every hand-object contact: sliding friction ``mu``; on the links
        of ``torsion`` also a torsional friction of ``torsion[link]`` [m]
        (the largest moment about the normal per newton of normal force)."""
        for g, link in self.hand_geoms.items():
            self.model.geom_friction[g] = (mu, torsion.get(link, 0.0), 0.0)

    # -- fingers -------------------------------------------------------------------
    def _set_motor(self, i: int, target: float, kp: float, kv: float, lower: float, upper: float) -> None:
        m = self.model
        m.actuator_gainprm[i, 0] = kp
        m.actuator_biasprm[i, :3] = (0.0, -kp, -kv)
        m.actuator_forcerange[i] = (lower, upper)
        self.data.ctrl[i] = target

    def drive(self, joint: str, target: float, kp: float, kv: float, force: float | tuple[float, float]) -> None:
        """A position servo on ``joint``: towards ``target`` [rad or m] with
        gain ``kp`` [N/m or N m/rad] and damping ``kv``, its force [N or N m]
        within ``force`` (a bound on both sides, or (lower, upper)); ``kp`` 0
        and force 0: the joint is free."""
        lower, upper = (-force, force) if isinstance(force, (int, float)) else force
        self._set_motor(self.motors[joint], target, kp, kv, lower, upper)

    def set_target(self, joint: str, target: float) -> None:
        self.data.ctrl[self.motors[joint]] = target

    def servo_io(self) -> tuple[np.ndarray, dict[str, int], np.ndarray, dict[str, int]]:
        """(the motors' targets (nu,) [rad or m], each joint's index in it, the joints' speeds (nv,) [rad/s or
        m/s], each joint's index in it): views of the state, for a loop that sets targets and reads speeds every
        step without a method call per joint and step (``ctrl[i[name]] = x`` is :meth:`set_target`,
        ``qvel[k[name]]`` :meth:`joint_speed`); valid as long as the world."""
        m = self.model
        return (self.data.ctrl, dict(self.motors), self.data.qvel,
                {name: int(m.jnt_dofadr[j]) for name, j in self.joints.items()})

    def couple(self, joint: str, engaged: bool) -> None:
        """Engage or release the gear (equality constraint) of a mimic joint."""
        self.data.eq_active[self.gears[joint]] = int(engaged)

    def set_limits(self, joint: str, lower: float, upper: float) -> None:
        """Move ``joint``'s limits [rad or m] (a ratchet, a brake: ``lower`` = ``upper`` holds it there),
        as stiff as the contacts (the engine's contact time constant) until the next :meth:`reset`."""
        i = self.joints[joint]
        self._range[i] = (lower, upper)
        self._solref[i] = self._held

    def joint_position(self, joint: str) -> float:
        return float(self._qpos[self._qpos_of[joint]])

    def motor_force(self, joint: str) -> float:
        """[N or N m] the force ``joint``'s motor applies now (within its force range)."""
        return float(self.data.actuator_force[self.motors[joint]])

    def joint_speed(self, joint: str) -> float:
        return float(self.data.qvel[self.model.jnt_dofadr[self.joints[joint]]])

    # -- running -------------------------------------------------------------------
    def set_gravity(self, g: np.ndarray) -> None:
        """(3,) [m/s^2] in the world frame."""
        self.model.opt.gravity[:] = g

    def step(self, n: int = 1) -> None:
        m, d = self.model, self.data
        for _ in range(n):
            mujoco.mj_step(m, d)

    def stepper(self) -> Callable[[], None]:
        """One :meth:`step` as a call without arguments (for a loop that steps one at a time)."""
        return partial(mujoco.mj_step, self.model, self.data)

    def diverged(self) -> bool:
        """Whether the state has diverged since the last :meth:`reset`:
        MuJoCo met a non-finite or huge position, velocity or acceleration
        (it then resets the state to the model's defaults, hand and object
        at the origin, and counts a warning), or the state is not finite now."""
        d = self.data
        return bool(d.warning.number[self._diverging].any()
                    or not (np.isfinite(d.qpos).all() and np.isfinite(d.qvel).all()))

    @property
    def time(self) -> float:
        return float(self.data.time)

    # -- reading -------------------------------------------------------------------
    def object_pose(self) -> np.ndarray:
        """(4, 4) the object frame in the world."""
        pose = _EYE.copy()
        pose[:3, :3] = self.data.xmat[self.object_body].reshape(3, 3)
        pose[:3, 3] = self.data.xpos[self.object_body]
        return pose

    def hand_pose(self) -> np.ndarray:
        """(4, 4) the hand's root frame in the world (where the weld holds it, not its target)."""
        body = self._hand_body
        pose = _EYE.copy()
        pose[:3, :3] = self.data.xmat[body].reshape(3, 3)
        pose[:3, 3] = self.data.xpos[body]
        return pose

    def centre_of_mass(self) -> np.ndarray:
        """(3,) [m] the object's centre of mass in the world."""
        return self.data.xipos[self.object_body].copy()

    def _hand_object(self):  # type: ignore[no-untyped-def]
        """(contact, hand link, sign) of each hand-object contact now; sign
        +1 when the contact normal points from the hand into the object."""
        d = self.data
        for i in range(d.ncon):
            c = d.contact[i]
            g1, g2 = int(c.geom1), int(c.geom2)
            if g1 in self.hand_geoms and g2 in self.object_geoms:
                yield c, self.hand_geoms[g1], 1.0
            elif g2 in self.hand_geoms and g1 in self.object_geoms:
                yield c, self.hand_geoms[g2], -1.0

    def touching_links(self) -> set[str]:
        """Hand links in contact with the object now (penetrating or touching)."""
        d = self.data
        if d.ncon == 0:  # read every step while a clutch is engaged: no Python loop over the contacts
            return set()
        contacts, hand, obj = d.contact, self.hand_geoms, self.object_geoms
        out = set()
        for g1, g2, dist in zip(contacts.geom1.tolist(), contacts.geom2.tolist(), contacts.dist.tolist()):
            if dist <= 0.0:
                if g1 in hand and g2 in obj:
                    out.add(hand[g1])
                elif g2 in hand and g1 in obj:
                    out.add(hand[g2])
        return out

    def depth(self) -> float:
        """[m] the deepest overlap of the hand and the object now (0 if none)."""
        return max([0.0] + [-float(c.dist) for c, _, _ in self._hand_object()])

    def contact_points(self) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
        """The hand-object contacts now, object frame: points (n, 3) [m],
        unit normals (n, 3) into the object, and each one's hand link."""
        rows = [(np.array(c.pos), sign * np.array(c.frame[:3]), link) for c, link, sign in self._hand_object()
                if c.dist <= 0.0]
        if not rows:
            return np.zeros((0, 3)), np.zeros((0, 3)), ()
        to_object = np.linalg.inv(self.object_pose())
        points = np.array([r[0] for r in rows]) @ to_object[:3, :3].T + to_object[:3, 3]
        normals = np.array([r[1] for r in rows]) @ to_object[:3, :3].T
        return points, normals, tuple(r[2] for r in rows)

    def contact_force(self) -> dict[str, float]:
        """[N] the normal force of the hand's contacts with the object, summed per link."""
        out: dict[str, float] = {}
        for i in range(self.data.ncon):
            c = self.data.contact[i]
            g1, g2 = int(c.geom1), int(c.geom2)
            link = self.hand_geoms.get(g1) if g2 in self.object_geoms else self.hand_geoms.get(g2) \
                if g1 in self.object_geoms else None
            if link is None or c.efc_address < 0:
                continue
            mujoco.mj_contactForce(self.model, self.data, i, self._force)
            out[link] = out.get(link, 0.0) + float(self._force[0])
        return out
