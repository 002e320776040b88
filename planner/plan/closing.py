"""Closing the hand on the object, OpenRAVE-grasper style, in PyBullet.

For one candidate (approach ray, roll, standoff, preshape):

1. place the open hand on the ray, the tool centre point ``start`` metres in front of the surface point; back
   off along the ray while it collides;
2. move along the approach until first contact (large steps while far, then conservative advancement: never
   farther than the measured clearance);
3. back off by the standoff;
4. close the fingers along the preshape's synergy; every finger DOF stops when a link it moves touches the
   object (the others keep closing) or at its joint limit; mimic joints follow their master. A driven joint
   flagged ``breakaway`` (the Barrett's TorqueSwitch) stops only its own links when one of those touches: its
   mimics (the distal joint) close on alone until their links touch or reach a limit, so the grasp is the
   configuration the real hand settles in;
5. a self-centring parallel jaw is re-centred (hand shifted along the finger axis so both fingers are
   symmetric while staying where they touched);
6. read the contacts: as contact patches (:mod:`planner.plan.patches`, the default), or as PyBullet's closest
   points spread over each link (``contacts="points"``, the legacy reading kept for comparisons). Rejected:
   start in collision, no contact, touching with a link that may not touch, or interpenetration.

The object frame is the world frame here (the object sits at the origin).

A finely meshed object (a scan) is closed against its collision proxy (:mod:`planner.geometry.proxy`,
:meth:`Grasper.for_object`): a decimation within a measured 0.5 mm of the exact mesh, so the cost of a closing
does not grow with the face count; the contacts are then read on the exact mesh (points moved onto it, its
normals at a contact's scale).

A table (optional, ``Grasper(..., table=frame)``: a frame on its top, object frame, z up) is an obstacle like
the object, GraspIt's way: the approach stops when the hand touches it (and backs off
:data:`~planner.plan.tolerances.TABLE_LIFT` along the approach, so that the fingers resting on it can close), a
finger that touches it stops, and a hand that ends overlapping it is rejected (``table``); contacts are read on
the object only. It is a slab (:data:`~planner.plan.tolerances.TABLE_SLAB`) whose top is the plane, so
everything under the plane overlaps it.

Speed (issue 16; the reference path, ``Grasper(..., reference=True)``, is the plain implementation the tests
compare against): "does the open hand overlap the object?" is one python-fcl boolean per hand shape against the
object's exact mesh (early exit) instead of every overlapping triangle pair from PyBullet; the speed bound of a
link about a revolute joint is computed once per (DOF, link) for every configuration instead of from the link's
box at every step; the simulator adapter converts poses in closed form; the standoffs of one (ray, roll,
preshape) approach once (issue 24: :meth:`Grasper.close` keeps the last approach).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial

import numpy as np
import trimesh

from planner.geometry.frames import hand_rotation
from planner.geometry.hulls import surface_hulls
from planner.geometry.proxy import collision_proxy
from planner.geometry.solid import PreparedObject
from planner.plan.closing_types import CONTACT_READINGS, Closed, CloseSettings, Rejected
from planner.plan.contact_reading import ContactReading
from planner.plan.finger_closing import DofMotion, FingerClosing
from planner.plan.obstacle_queries import Bounded, ObstacleQueries
from planner.plan.patches import ObjectSurface
from planner.plan.tolerances import TABLE_LIFT, TABLE_SLAB
from planner.sim import Body, Sim
from planner.sim import fcl as overlap
from planner.specs.hands import HandSpec
from planner.specs.preshapes import Preshape

__all__ = ["CONTACT_READINGS", "RELATIVE_CACHE", "Bounded", "CloseSettings", "Closed", "Grasper", "Rejected"]

#: Joint configurations whose hand shapes (relative to the palm) are kept for
#: overlap tests: the candidates of one antipodal pair share one.
RELATIVE_CACHE = 64


@dataclass
class Grasper(FingerClosing, ContactReading, ObstacleQueries):
    """Closes one hand on one static object inside one :class:`Sim` (closing
    the fingers: :mod:`planner.plan.finger_closing`; reading the contacts:
    :mod:`planner.plan.contact_reading`; asking the simulator what is near:
    :mod:`planner.plan.obstacle_queries`)."""

    sim: Sim
    hand: HandSpec
    object_body: int
    settings: CloseSettings = field(default_factory=CloseSettings)
    mesh: trimesh.Trimesh | None = None  # the object's mesh (object frame); default: the body's
    reference: bool = False  # the plain implementation the fast one is tested against
    exact: trimesh.Trimesh | None = None  # the exact surface when ``mesh`` is a proxy: contact points go onto it
    table: np.ndarray | None = None  # (4, 4) a frame on a table top, object frame, z up; None: no table

    @classmethod
    def for_mesh(cls, sim: Sim, hand: HandSpec, mesh: trimesh.Trimesh,
                 settings: CloseSettings | None = None, table: np.ndarray | None = None) -> Grasper:
        """A grasper on ``mesh`` added to ``sim`` as a static body at the origin (and a table at ``table``)."""
        return cls(sim, hand, sim.add_static_mesh(mesh.vertices, mesh.faces), settings or CloseSettings(), mesh=mesh,
                   table=table)

    @classmethod
    def for_object(cls, sim: Sim, hand: HandSpec, obj: PreparedObject,
                   settings: CloseSettings | None = None, table: np.ndarray | None = None) -> Grasper:
        """A grasper on the object's collision proxy (:mod:`planner.geometry.proxy`:
        the exact mesh unless it has more than ``ProxySettings.above`` faces),
        with contact points moved onto the exact mesh (and a table whose top is
        at ``table``, if given)."""
        proxy = collision_proxy(obj.mesh, obj.mesh_hash, name=obj.name)
        if proxy.exact:
            return cls.for_mesh(sim, hand, obj.mesh, settings, table)
        return cls(sim, hand, sim.add_static_mesh(proxy.mesh.vertices, proxy.mesh.faces), settings or CloseSettings(),
                   mesh=proxy.mesh, exact=obj.mesh, table=table)

    def __post_init__(self) -> None:
        self.body: Body = self.sim.load_urdf(self.hand.urdf)
        self.names = {index: name for name, index in self.body.links.items()}
        self.geometry = tuple(n for n in self.hand.links if self.sim.has_collision(self.body, n))
        self._front: dict[str, float] = {}
        # the prismatic finger axes in the hand frame, read once with the hand at the origin: read at a
        # candidate's pose they differ in the last bits with that pose, and so a unit's grasps with the
        # candidates before them (a sweep split into other chunks closed ~5e-10 m apart)
        self._place(np.eye(4), {})
        self._axes: dict[str, np.ndarray] = {j.name: self.sim.joint_axis_in_base(self.body, j.name)
                                             for j in self.hand.joints if j.kind == "prismatic"}
        if not self.reference:  # the speed bounds' parts, from the hand alone (not from the first pose closed)
            self._measure_arms()
            self._place(np.eye(4), {j.name: 0.0 for j in self.hand.joints})
        self._bounds: dict[tuple, dict[str, float]] = {}
        self._motions: dict[tuple, DofMotion] = {}
        self._relative: dict[tuple, list[np.ndarray]] = {}
        self._approached: tuple[tuple, Preshape, np.ndarray | Rejected] | None = None  # close()'s last approach
        self.queries = 0
        self.contact_seconds = 0.0  # time spent reading contacts (benchmarks)
        known = self.sim.meshes.get(self.object_body)
        if self.mesh is None and known is not None:
            self.mesh = trimesh.Trimesh(*known, process=False)
        self.shapes: overlap.LinkShapes | None = None
        self.far_body: int | None = None
        if known is not None and not self.reference:
            self.shapes = overlap.LinkShapes(self.sim, self.body, self.hand.urdf, self.geometry)
            self.object_bvh = overlap.object_bvh(*known)
            self.far_body = self.sim.add_static_hulls(surface_hulls(self.mesh))
            self._far_box = tuple(map(tuple, self.sim.body_box(self.far_body)))
            self._indices = tuple(self.body.links[n] for n in reversed(self.geometry))  # the tips first: nearest
        self.surface = None if self.mesh is None else ObjectSurface(self.mesh, self.settings.patches)
        self.exact_surface = None if self.exact is None else ObjectSurface(self.exact, self.settings.patches)
        self.table_body: int | None = None
        self.table_shape = None
        if self.table is not None:
            slab = np.array(self.table, float)  # the slab's centre: half its thickness under the top
            slab[:3, 3] -= slab[:3, 2] * TABLE_SLAB[2]
            self.table_body = self.sim.add_box(TABLE_SLAB, slab)
            self.table_shape = None if self.shapes is None else overlap.box(TABLE_SLAB, slab)

    # -- queries: planner.plan.obstacle_queries ------------------------------
    def normals_at(self) -> Callable[[np.ndarray, np.ndarray], np.ndarray] | None:
        """A proxied mesh's outward normals at (points (n, 3), faces (n,)) of its exact surface, averaged at a
        contact's scale as its contacts read them (:mod:`planner.geometry.normals`); None when closing collides
        with the exact mesh (then the faces' own normals)."""
        exact = self.exact_surface
        return None if exact is None else partial(exact.scale_normals.at, radius=self.settings.patches.normal_radius)

    def on_table(self, within: float = 0.0) -> bool:
        """Is the hand, where it is now, within ``within`` [m] of the table or overlapping it (False without one)?"""
        if self.table_body is None:
            return False
        return len(self.sim.closest(self.body.uid, self.table_body, within - self.hand.distance_offset)) > 0

    def on_table_at(self, pose: np.ndarray, joints: dict[str, float]) -> bool:
        """Would the hand at ``pose`` with ``joints`` touch the table? (Moves the hand there.)"""
        self._place(np.asarray(pose, float), joints)
        return self.on_table()

    def overlaps(self) -> bool:
        """Does the hand, where it is now, overlap the object (touching counts)?"""
        if self.shapes is None:
            return self._gap(self._obstacles(0.0)) <= 0.0
        self.shapes.update()
        return self.shapes.collides(self.object_bvh) or (self.table_shape is not None and
                                                         self.shapes.collides(self.table_shape))

    def _place(self, pose: np.ndarray, joints: dict[str, float]) -> None:
        self.sim.set_pose(self.body, pose)
        self.sim.set_joints(self.body, joints)

    def front(self, preshape: Preshape) -> float:
        """How far [m] the open hand reaches past its tool centre point."""
        if preshape.name not in self._front:
            self._place(np.eye(4), preshape.joints)
            reach = 0.0
            for link in self.geometry:
                lo, hi = self.sim.link_aabb(self.body, link)
                corners = np.array(np.meshgrid(*zip(lo, hi))).T.reshape(-1, 3)
                reach = max(reach, float(np.max((corners - preshape.tcp) @ self.hand.approach)))
            self._front[preshape.name] = reach
        return self._front[preshape.name]

    # -- the stages ----------------------------------------------------------
    def close(self, point: np.ndarray, direction: np.ndarray, roll: float, standoff: float,
              preshape: Preshape, object_radius: float) -> Closed | Rejected:
        self.queries = 0
        key = (np.asarray(point, float).tobytes(), np.asarray(direction, float).tobytes(), float(roll),
               float(object_radius))
        if self._approached is None or self._approached[0] != key or self._approached[1] is not preshape:
            self._approached = (key, preshape, self._approach(point, direction, roll, preshape, object_radius))
        approached = self._approached[2]
        if isinstance(approached, Rejected):
            return approached
        pose = approached.copy()
        joints = dict(preshape.joints)
        self._place(pose, joints)  # the hand as the approach left it (a standoff before may have closed its fingers)
        pose[:3, 3] -= direction * standoff
        self.sim.set_pose(self.body, pose)
        return self._finish(pose, preshape, joints)

    def _approach(self, point: np.ndarray, direction: np.ndarray, roll: float, preshape: Preshape,
                  object_radius: float) -> np.ndarray | Rejected:
        """Steps 1-2 (and the table's lift): the (4, 4) pose at first contact, or why there is none; the same
        for every standoff, so :meth:`close` keeps the last (the hand put back there: every value the same)."""
        s = self.settings
        rotation = hand_rotation(self.hand.approach, direction, roll)
        pose = np.eye(4)
        pose[:3, :3] = rotation
        start = self.front(preshape) + s.start_margin
        pose[:3, 3] = point - direction * start - rotation @ preshape.tcp
        joints = dict(preshape.joints)
        self._place(pose, joints)
        backed = self._back_off(pose, direction, 2 * object_radius)
        if backed is None:
            return Rejected("start_collision", self.queries)
        # the hand may travel until its back (not just its tcp) has passed the object
        depth = float(np.linalg.norm(preshape.tcp))
        travelled, limit = 0.0, start + backed + 2 * object_radius + depth
        while True:
            touching, step = self._translation_step(self._obstacles(s.coarse_step + s.gap), direction)
            if touching:
                break
            travelled += step
            if travelled > limit:
                return Rejected("missed", self.queries)
            pose[:3, 3] += direction * step
            self.sim.set_pose(self.body, pose)
        if self.on_table(s.contact_tol):  # stopped by the table: lift off it, or a finger resting on it cannot close
            pose[:3, 3] -= direction * TABLE_LIFT
        return pose

    def close_at(self, pose: np.ndarray, preshape: Preshape, max_back_off: float = 0.05) -> Closed | Rejected:
        """Close the fingers with the hand at ``pose`` (no approach): for re-scoring a given grasp pose (imports,
        noisy copies of a grasp). The open hand is backed off along the approach only while it collides."""
        self.queries = 0
        pose = np.array(pose, float)
        joints = dict(preshape.joints)
        self._place(pose, joints)
        if self._back_off(pose, pose[:3, :3] @ self.hand.approach, max_back_off) is None:
            return Rejected("start_collision", self.queries)
        return self._finish(pose, preshape, joints)

    def overlaps_at(self, pose: np.ndarray, joints: dict[str, float]) -> bool:
        """Would the hand at ``pose`` with ``joints`` overlap the object? (The fast path asks the simulator only
        once per joint configuration.)"""
        if self.shapes is None:
            self._place(pose, joints)
            return self.overlaps()
        key = tuple(joints.items())
        relative = self._relative.get(key)
        if relative is None:
            if len(self._relative) >= RELATIVE_CACHE:
                self._relative.clear()
            self._place(np.eye(4), joints)
            relative = self._relative[key] = self.shapes.frames()
        return self.shapes.collides_at(pose, relative, self.object_bvh) or (
            self.table_shape is not None and self.shapes.collides_at(pose, relative, self.table_shape))

    def close_from(self, pose: np.ndarray, preshape: Preshape, joints: dict[str, float], near: bool = False
                   ) -> Closed | Rejected:
        """Close the fingers from ``joints`` (every finger joint, open) with the hand at ``pose``, no approach and
        no back-off: the antipodal sampler's candidates, placed where they grasp (the caller has checked that the
        open hand is free). The grasp records ``joints`` as its open joints. ``near``: the fingers are expected
        near the object from the start (a squeeze's closing, opened a millimetre: they ask the exact mesh first,
        :meth:`~planner.plan.obstacle_queries.ObstacleQueries._closest_near`; the same closing)."""
        self.queries = 0
        pose = np.array(pose, float)
        self._place(pose, joints)
        return self._finish(pose, preshape, dict(joints), {j.name: joints[j.name] for j in self.hand.driven}, near)

    def _back_off(self, pose: np.ndarray, direction: np.ndarray, limit: float) -> float | None:
        """Move the hand back along ``direction`` in doubling jumps until it is free; how far it went, or None
        past ``limit``. Moves ``pose`` in place."""
        backed, jump = 0.0, self.settings.coarse_step
        while self.overlaps():
            if backed > limit:
                return None
            pose[:3, 3] -= direction * jump
            backed += jump
            jump *= 2
            self.sim.set_pose(self.body, pose)
        return backed

    def _finish(self, pose: np.ndarray, preshape: Preshape, joints: dict[str, float],
                open_joints: dict[str, float] | None = None, near: bool = False) -> Closed | Rejected:
        closed = self._close_fingers(preshape, joints, near)
        if self.hand.centering:
            pose, closed = self._centre(pose, closed)
            self._place(pose, closed)
        if self.on_table():
            return Rejected("table", self.queries)
        t = time.perf_counter()
        out = self._read(pose, preshape.joints if open_joints is None else open_joints, closed)
        self.contact_seconds += time.perf_counter() - t
        return out
