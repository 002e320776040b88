"""The MuJoCo adapter: the only module that imports mujoco.

It builds one world from a hand (its URDF, as the hand spec has cut it) and a
free object, both written as MJCF in code, and offers what a dynamic trial
needs: placing bodies, driving finger joints, coupling and uncoupling mimic
joints, moving the hand, stepping, reading contacts. The protocol that uses
it is elsewhere (:mod:`planner.validation.mujoco_trial`).

The world frame is the object's frame at rest (the object starts at the
identity); the hand's root link is a free body welded to a mocap body, so a
trial moves the hand by moving the mocap target and the contacts see the
hand's real velocity. Poses are 4x4 homogeneous matrices [m]; MuJoCo's
quaternions (w, x, y, z) never leave this module.

Model (one per hand and object, compiled once and reused for every grasp):

- every URDF link below the root is a body at its joint's origin, with the
  URDF's inertial; revolute and prismatic joints with their limits; each
  collision element a geom (boxes, cylinders and spheres as MuJoCo
  primitives, meshes as their convex hulls, as MuJoCo collides them);
- a mimic joint is an equality constraint ``q = multiplier q_master + offset``;
- every finger joint has a position actuator whose gain and force range the
  trial sets (:meth:`World.drive`): 0 is an idle motor;
- hand bodies are gravity-compensated (the arm carries the hand) and never
  collide with each other; the hand's geoms have priority in a contact with
  the object, so the trial sets the contact's friction on the hand alone
  (:meth:`World.set_friction`): sliding ``mu``, and on soft links torsional
  ``mu x torsion_radius`` (condim 4, elliptic cones);
- the object is one free body: a box, sphere or cylinder primitive, or its
  convex parts, with the given mass, centre of mass and inertia.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import mujoco
import numpy as np
import trimesh

from planner.errors import SimulationError
from planner.specs.hands import HandSpec
from planner.specs.urdf import load_model
from planner.validation.mujoco_settings import Engine

log = logging.getLogger(__name__)
# MuJoCo's warnings (a diverged state it resets, a full contact buffer) go to the log, not to stdout and a
# MUJOCO_LOG.TXT in the user's working directory; each world still counts them (World.diverged).
mujoco.set_mju_user_warning(lambda message: log.warning("MuJoCo: %s", message))

#: Collision bits: hand geoms collide with the object only, never with each other.
_HAND_BITS, _OBJECT_BITS = 1, 2
#: [kg] and [kg m^2] given to a link the URDF leaves without mass (MuJoCo needs some on moving bodies).
_MIN_MASS, _MIN_INERTIA = 1e-3, 1e-7
#: MuJoCo's warnings of a diverged state (each followed by a reset of the state).
_DIVERGED = (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL, mujoco.mjtWarning.mjWARN_BADQACC)
#: Name of the object's body and of the hand's mocap target.
OBJECT, TARGET = "__object", "__hand_target"


@dataclass(frozen=True)
class Solid:
    """The free object as MuJoCo builds it, object frame [m].

    ``kind``: ``box`` (``dims`` = extents), ``sphere`` (radius), ``cylinder``
    (radius, height along z), each centred on the object frame, or ``hulls``:
    convex parts, each a (k_i, 3) vertex array. ``mass`` [kg], ``com`` (3,)
    [m] and ``inertia`` (3, 3) [kg m^2] about the centre of mass, object axes.
    """

    kind: str
    dims: tuple[float, ...]
    hulls: tuple[np.ndarray, ...]
    mass: float
    com: np.ndarray
    inertia: np.ndarray

    def __post_init__(self) -> None:
        if self.kind not in ("box", "sphere", "cylinder", "hulls"):
            raise ValueError(f"Solid.kind must be box, sphere, cylinder or hulls, not {self.kind!r}")
        if self.com.shape != (3,) or self.inertia.shape != (3, 3):
            raise ValueError("Solid.com must be (3,), Solid.inertia (3, 3)")
        if self.kind == "hulls" and not all(h.ndim == 2 and h.shape[1] == 3 and len(h) >= 4 for h in self.hulls):
            raise ValueError("Solid.hulls must be (k, 3) vertex arrays of at least 4 vertices")


def _f(values: Sequence[float] | np.ndarray) -> str:
    return " ".join(f"{float(v):.10g}" for v in np.ravel(values))


def _quat(rotation: np.ndarray) -> np.ndarray:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(rotation, float).ravel())
    return q


def _pose_attrs(pose: np.ndarray | None) -> str:
    if pose is None:
        return ""
    return f'pos="{_f(pose[:3, 3])}" quat="{_f(_quat(pose[:3, :3]))}"'


@cache
def _hull(path: str, scale: tuple[float, float, float]) -> np.ndarray:
    """(k, 3) convex hull vertices of a mesh file, scaled."""
    mesh = trimesh.load(path, force="mesh")
    return np.asarray(mesh.convex_hull.vertices, float) * np.asarray(scale)


def _inertial(mass: float, com: np.ndarray, inertia: np.ndarray, frame: np.ndarray | None = None) -> str:
    """An <inertial> of ``mass`` at ``com``, ``inertia`` about it in the axes of ``frame`` (3, 3)."""
    inertia = np.asarray(inertia, float)
    if frame is not None:
        inertia = frame @ inertia @ frame.T
    moments, axes = np.linalg.eigh(0.5 * (inertia + inertia.T))
    if np.linalg.det(axes) < 0:
        axes[:, 0] *= -1
    moments = np.maximum(moments, _MIN_INERTIA)
    return (f'<inertial pos="{_f(com)}" quat="{_f(_quat(axes))}" mass="{max(mass, _MIN_MASS):.10g}" '
            f'diaginertia="{_f(moments)}"/>')


class _Builder:
    """MJCF text of a hand (its URDF) and an object."""

    def __init__(self, hand: HandSpec) -> None:
        self.hand = hand
        self.model = load_model(hand.urdf)
        self.meshes: list[str] = []
        self.soft = {name for name, c in hand.contacts.items() if c.model == "soft" and c.torsion_radius > 0}

    def _mesh(self, vertices: np.ndarray) -> str:
        name = f"mesh{len(self.meshes)}"
        self.meshes.append(f'<mesh name="{name}" vertex="{_f(vertices)}"/>')
        return name

    def _geom(self, element, link: str, index: int) -> str:  # type: ignore[no-untyped-def]
        g = element.geometry
        where = _pose_attrs(element.origin)
        condim = 4 if link in self.soft else 3
        common = (f'name="{link}#{index}" {where} contype="{_HAND_BITS}" conaffinity="{_OBJECT_BITS}" '
                  f'condim="{condim}" priority="1" group="1"')
        if g.box is not None:
            return f'<geom type="box" size="{_f(np.asarray(g.box.size) / 2)}" {common}/>'
        if g.cylinder is not None:
            return f'<geom type="cylinder" size="{g.cylinder.radius:.10g} {g.cylinder.length / 2:.10g}" {common}/>'
        if g.sphere is not None:
            return f'<geom type="sphere" size="{g.sphere.radius:.10g}" {common}/>'
        if g.mesh is not None:
            scale = (1.0, 1.0, 1.0) if g.mesh.scale is None else tuple(
                float(s) for s in np.broadcast_to(np.asarray(g.mesh.scale, float), (3,)))
            path = Path(self.hand.urdf).parent / g.mesh.filename.replace("package://", "")
            return f'<geom type="mesh" mesh="{self._mesh(_hull(str(path), scale))}" {common}/>'
        return ""

    def _body(self, link: str, pose: np.ndarray | None, joint) -> str:  # type: ignore[no-untyped-def]
        node = self.model.link_map[link]
        parts = [f'<body name="{link}" {_pose_attrs(pose)} gravcomp="1">']
        if pose is None:
            parts.append('<freejoint name="__hand_base"/>')
        inertial = node.inertial
        if inertial is not None and inertial.mass is not None and inertial.mass > 0:
            origin = np.eye(4) if inertial.origin is None else inertial.origin
            tensor = np.eye(3) * _MIN_INERTIA if inertial.inertia is None else inertial.inertia
            parts.append(_inertial(inertial.mass, origin[:3, 3], tensor, origin[:3, :3]))
        else:
            parts.append(_inertial(_MIN_MASS, np.zeros(3), np.eye(3) * _MIN_INERTIA))
        if joint is not None and joint.type in ("revolute", "prismatic", "continuous"):
            kind = "slide" if joint.type == "prismatic" else "hinge"
            limit = joint.limit
            bounds = ""
            if joint.type != "continuous" and limit is not None and limit.lower is not None:
                bounds = f'limited="true" range="{limit.lower:.10g} {limit.upper:.10g}"'
            axis = np.array([1.0, 0.0, 0.0]) if joint.axis is None else np.asarray(joint.axis, float)
            parts.append(f'<joint name="{joint.name}" type="{kind}" axis="{_f(axis)}" {bounds} damping="0" '
                         'armature="0.0001"/>')
        parts += [self._geom(c, link, i) for i, c in enumerate(node.collisions)]
        for child_joint in self.model.robot.joints:
            if child_joint.parent == link:
                origin = np.eye(4) if child_joint.origin is None else child_joint.origin
                parts.append(self._body(child_joint.child, origin, child_joint))
        parts.append("</body>")
        return "\n".join(p for p in parts if p)

    def xml(self, solid: Solid, engine: Engine) -> str:
        hand = self._body(self.hand.root_link, None, None)
        obj = self._object(solid)
        equality = [f'<weld body1="{TARGET}" body2="{self.hand.root_link}" relpose="0 0 0 1 0 0 0" '
                    f'solref="{engine.weld_time:.10g} 1"/>']
        for j in self.hand.joints:
            if j.mimic is not None:
                equality.append(f'<joint name="gear:{j.name}" joint1="{j.name}" joint2="{j.mimic}" '
                                f'polycoef="{j.offset:.10g} {j.multiplier:.10g} 0 0 0" solref="0.004 1"/>')
        actuators = [f'<position name="motor:{j.name}" joint="{j.name}" kp="0" forcelimited="true" '
                     'forcerange="-1 1"/>' for j in self.hand.joints]
        flags = '<flag multiccd="enable"/>' if engine.multiccd else ""
        return f"""<mujoco model="grasp">
<compiler angle="radian" autolimits="true"/>
<option timestep="{engine.timestep:.10g}" iterations="{engine.iterations}" integrator="implicitfast"
 cone="elliptic" impratio="{engine.impratio:.10g}" solver="Newton" gravity="0 0 0">{flags}</option>
<default><geom solref="{engine.contact_time:.10g} {engine.contact_damping:.10g}" solimp="0.95 0.99 0.001"
 friction="1 0 0"/></default>
<asset>
{chr(10).join(self.meshes)}
</asset>
<worldbody>
<body name="{TARGET}" mocap="true"/>
{hand}
{obj}
</worldbody>
<equality>
{chr(10).join(equality)}
</equality>
<actuator>
{chr(10).join(actuators)}
</actuator>
</mujoco>"""

    def _object(self, solid: Solid) -> str:
        common = f'contype="{_OBJECT_BITS}" conaffinity="{_HAND_BITS}" condim="3" priority="0" group="2"'
        if solid.kind == "box":
            geoms = [f'<geom type="box" size="{_f(np.asarray(solid.dims) / 2)}" {common}/>']
        elif solid.kind == "sphere":
            geoms = [f'<geom type="sphere" size="{solid.dims[0]:.10g}" {common}/>']
        elif solid.kind == "cylinder":
            geoms = [f'<geom type="cylinder" size="{solid.dims[0]:.10g} {solid.dims[1] / 2:.10g}" {common}/>']
        else:
            geoms = [f'<geom type="mesh" mesh="{self._mesh(h)}" {common}/>' for h in solid.hulls]
        return "\n".join([f'<body name="{OBJECT}"><freejoint name="{OBJECT}"/>',
                          _inertial(solid.mass, solid.com, solid.inertia), *geoms, "</body>"])


def build(hand: HandSpec, solid: Solid, engine: Engine | None = None) -> World:
    """A compiled world of ``hand`` and ``solid`` (MuJoCo's compile errors as SimulationError)."""
    builder = _Builder(hand)
    engine = engine or Engine()
    xml = builder.xml(solid, engine)
    try:
        model = mujoco.MjModel.from_xml_string(xml)
    except ValueError as exc:
        raise SimulationError(f"MuJoCo cannot build hand '{hand.name}' with this object: {exc}") from exc
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
        self._base = m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "__hand_base")]
        self._base_dof = m.jnt_dofadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "__hand_base")]
        obj_joint = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, OBJECT)
        self._object_q, self._object_v = m.jnt_qposadr[obj_joint], m.jnt_dofadr[obj_joint]
        self.joints = {j.name: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j.name) for j in hand.joints}
        self.motors = {j.name: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, f"motor:{j.name}")
                       for j in hand.joints}
        self.gears = {j.name: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_EQUALITY, f"gear:{j.name}")
                      for j in hand.joints if j.mimic is not None}
        #: hand geom index -> its link's name; the object's geoms
        self.hand_geoms = {g: self._name(mujoco.mjtObj.mjOBJ_BODY, int(m.geom_bodyid[g]))
                           for g in range(m.ngeom) if m.geom_contype[g] == _HAND_BITS}
        self.object_geoms = frozenset(g for g in range(m.ngeom) if int(m.geom_bodyid[g]) == self.object_body)
        self._ranges, self._solrefs = m.jnt_range.copy(), m.jnt_solref.copy()
        self._force = np.zeros(6)

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

    def couple(self, joint: str, engaged: bool) -> None:
        """Engage or release the gear (equality constraint) of a mimic joint."""
        self.data.eq_active[self.gears[joint]] = int(engaged)

    def set_limits(self, joint: str, lower: float, upper: float) -> None:
        """Move ``joint``'s limits [rad or m] (a ratchet, a brake: ``lower`` = ``upper`` holds it there),
        as stiff as the contacts (the engine's contact time constant) until the next :meth:`reset`."""
        i = self.joints[joint]
        self.model.jnt_range[i] = (lower, upper)
        self.model.jnt_solref[i] = self._held

    def joint_position(self, joint: str) -> float:
        return float(self.data.qpos[self.model.jnt_qposadr[self.joints[joint]]])

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

    def diverged(self) -> bool:
        """Whether the state has diverged since the last :meth:`reset`:
        MuJoCo met a non-finite or huge position, velocity or acceleration
        (it then resets the state to the model's defaults, hand and object
        at the origin, and counts a warning), or the state is not finite now."""
        d = self.data
        return (any(d.warning[w].number for w in _DIVERGED)
                or not (np.all(np.isfinite(d.qpos)) and np.all(np.isfinite(d.qvel))))

    @property
    def time(self) -> float:
        return float(self.data.time)

    # -- reading -------------------------------------------------------------------
    def object_pose(self) -> np.ndarray:
        """(4, 4) the object frame in the world."""
        pose = np.eye(4)
        pose[:3, :3] = self.data.xmat[self.object_body].reshape(3, 3)
        pose[:3, 3] = self.data.xpos[self.object_body]
        return pose

    def hand_pose(self) -> np.ndarray:
        """(4, 4) the hand's root frame in the world (where the weld holds it, not its target)."""
        body = int(self.model.jnt_bodyid[mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_JOINT, "__hand_base")])
        pose = np.eye(4)
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
        return {link for c, link, _ in self._hand_object() if c.dist <= 0.0}

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
