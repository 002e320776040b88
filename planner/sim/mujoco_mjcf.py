"""The MJCF text of a MuJoCo trial's world: a hand (its URDF, as the hand
spec has cut it) and a free object, written in code. Pure text (numpy and
trimesh, no mujoco): :mod:`planner.sim.mujoco_world` compiles it and runs it.

Model (one per hand and object, compiled once and reused for every grasp):

- every URDF link below the root is a body at its joint's origin, with the
  URDF's inertial (its moments those of hand.toml's ``[dynamics.link_inertia]`` where
  given: :attr:`~planner.specs.hand_spec.HandSpec.link_inertia`); revolute and prismatic joints with their limits; each
  collision element a geom (cylinders as MuJoCo primitives, meshes as their
  convex hulls, as MuJoCo collides them; a hand's collision boxes and
  spheres are meshes already in its cut URDF:
  :func:`planner.specs.urdf.cut_subtree`);
- the hand's root link is a free body welded to a mocap body (``TARGET``);
- a mimic joint is an equality constraint ``q = multiplier q_master + offset``;
- every finger joint has a position actuator (``motor:<joint>``) whose gain and force range the
  trial sets: 0 is an idle motor;
- hand bodies are gravity-compensated (the arm carries the hand) and never
  collide with each other (collision bits ``HAND_BITS``, ``OBJECT_BITS``); the hand's geoms have
  priority in a contact with the object, so the trial sets the contact's friction on the hand alone:
  on soft links condim 4 (torsional friction), elliptic cones;
- the object (``OBJECT``) is one free body: a box, sphere or cylinder primitive, or its
  convex parts, with the given mass, centre of mass and inertia.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache

import numpy as np
import trimesh

from planner.specs.hands import HandSpec
from planner.specs.urdf import load_model, mesh_path
from planner.validation.mujoco_settings import Engine

#: Collision bits: hand geoms collide with the object only, never with each other.
HAND_BITS, OBJECT_BITS = 1, 2
#: [kg] and [kg m^2] given to a link the URDF leaves without mass (MuJoCo needs some on moving bodies).
_MIN_MASS, _MIN_INERTIA = 1e-3, 1e-7
#: Name of the object's body (and its free joint), of the hand's mocap target and of the hand's free joint.
OBJECT, TARGET, HAND_BASE = "__object", "__hand_target", "__hand_base"


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


def quat(rotation: np.ndarray) -> np.ndarray:
    """(4,) unit quaternion (w, x, y, z) of a (3, 3) rotation (:func:`quats` of one)."""
    return quats(np.asarray(rotation, float)[None])[0]


def quats(rotations: np.ndarray) -> np.ndarray:
    """(n, 4) unit quaternions (w, x, y, z) of (n, 3, 3) rotations, by the branches of MuJoCo's
    mju_mat2Quat (the largest of w, x, y, z from the diagonal, the others from it)."""
    m = np.asarray(rotations, float).reshape(-1, 9)
    q = np.zeros((len(m), 4))
    trace = m[:, 0] + m[:, 4] + m[:, 8]
    w = trace > 0
    x = ~w & (m[:, 0] > m[:, 4]) & (m[:, 0] > m[:, 8])
    y = ~w & ~x & (m[:, 4] > m[:, 8])
    z = ~w & ~x & ~y
    r = m[w]
    q[w, 0] = 0.5 * np.sqrt(1 + r[:, 0] + r[:, 4] + r[:, 8])
    q[w, 1:] = 0.25 * np.stack([r[:, 7] - r[:, 5], r[:, 2] - r[:, 6], r[:, 3] - r[:, 1]], 1) / q[w, :1]
    r = m[x]
    q[x, 1] = 0.5 * np.sqrt(1 + r[:, 0] - r[:, 4] - r[:, 8])
    q[np.ix_(x, [0, 2, 3])] = 0.25 * np.stack([r[:, 7] - r[:, 5], r[:, 1] + r[:, 3], r[:, 2] + r[:, 6]], 1) \
        / q[x, 1:2]
    r = m[y]
    q[y, 2] = 0.5 * np.sqrt(1 - r[:, 0] + r[:, 4] - r[:, 8])
    q[np.ix_(y, [0, 1, 3])] = 0.25 * np.stack([r[:, 2] - r[:, 6], r[:, 1] + r[:, 3], r[:, 5] + r[:, 7]], 1) \
        / q[y, 2:3]
    r = m[z]
    q[z, 3] = 0.5 * np.sqrt(1 - r[:, 0] - r[:, 4] + r[:, 8])
    q[z, :3] = 0.25 * np.stack([r[:, 3] - r[:, 1], r[:, 2] + r[:, 6], r[:, 5] + r[:, 7]], 1) / q[z, 3:]
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def _pose_attrs(pose: np.ndarray | None) -> str:
    if pose is None:
        return ""
    return f'pos="{_f(pose[:3, 3])}" quat="{_f(quat(pose[:3, :3]))}"'


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
    return (f'<inertial pos="{_f(com)}" quat="{_f(quat(axes))}" mass="{max(mass, _MIN_MASS):.10g}" '
            f'diaginertia="{_f(moments)}"/>')


class Builder:
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
        common = (f'name="{link}#{index}" {where} contype="{HAND_BITS}" conaffinity="{OBJECT_BITS}" '
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
            path = mesh_path(self.hand.urdf, g.mesh.filename)
            return f'<geom type="mesh" mesh="{self._mesh(_hull(str(path), scale))}" {common}/>'
        return ""

    def _body(self, link: str, pose: np.ndarray | None, joint) -> str:  # type: ignore[no-untyped-def]
        node = self.model.link_map[link]
        parts = [f'<body name="{link}" {_pose_attrs(pose)} gravcomp="1">']
        if pose is None:
            parts.append(f'<freejoint name="{HAND_BASE}"/>')
        inertial = node.inertial
        if inertial is not None and inertial.mass is not None and inertial.mass > 0:
            origin = np.eye(4) if inertial.origin is None else inertial.origin
            tensor = np.eye(3) * _MIN_INERTIA if inertial.inertia is None else inertial.inertia
            if link in self.hand.link_inertia:  # the URDF's is a placeholder (hand.toml [dynamics.link_inertia])
                tensor = np.diag(self.hand.link_inertia[link])
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
        off = ([] if engine.multiccd else ['multiccd="disable"']) + ([] if engine.islands else ['island="disable"'])
        flags = f"<flag {' '.join(off)}/>" if off else ""  # MuJoCo 4: both on unless disabled
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
        common = f'contype="{OBJECT_BITS}" conaffinity="{HAND_BITS}" condim="3" priority="0" group="2"'
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
