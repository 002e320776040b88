"""The python-fcl adapter: the only module that imports ``fcl``.

What it is used for, and why (measured in ``bench/fcl_vs_pybullet.py``,
figures in bench/RESULTS.md): *yes/no overlap* of a hand against an object's
exact mesh. ``fcl.collide`` stops at the first overlapping triangle pair,
while PyBullet's ``getClosestPoints`` returns every pair within range at
~4-5 us each (an open Panda hand overlapping the concave mug: 30-130 pairs,
0.2-1.2 ms, against 20-30 us here). PyBullet keeps everything else: it alone
returns every pair within a range *with a normal*, which closing's
directional bound and the contact reading need, and it answers "nothing
within range" in 3-7 us where fcl always computes the exact distance.

python-fcl 0.7 behaviour this module works around (so callers need not):

- ``fcl.distance`` of a (shape, BVH) pair returns the nearest points in
  (BVH, shape) order: the BVH always goes first here;
- distance between overlapping BVH pairs is -1 (no depth); Convex-Box
  distance is wrong for face-parallel boxes and Convex-Halfspace distance
  crashes: only :meth:`LinkShapes.collides`, the BVH-first
  :meth:`LinkShapes.distance` and :class:`LinkGap`'s convex-convex signed
  distance (GJK apart, EPA's depth overlapping: PyBullet's closest points
  less its margins within 1 um on the PR2's pads, tests/sim/test_fcl.py)
  are offered.

Geometry is read from the URDF (one fcl shape per ``<collision>`` element,
as PyBullet makes one per element): ``<mesh>`` as the convex hull of the
scaled mesh file (PyBullet collides a URDF mesh as its hull), ``<box>``,
``<cylinder>``, ``<sphere>`` as fcl primitives (PyBullet turns a URDF
cylinder into a 32-sided hull: up to ~0.2 mm apart; a hand's collision
boxes and spheres are meshes in its cut URDF,
:func:`planner.specs.urdf.cut_subtree`, so they reach here as hulls). fcl
shapes carry no collision margin: they are the true geometry.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import cache
from pathlib import Path

import fcl
import numpy as np
import trimesh

from planner.errors import ConfigError
from planner.sim import Body, Sim, pb, pb_to_pose
from planner.specs.urdf import load_model


def object_bvh(vertices: np.ndarray, faces: np.ndarray, pose: np.ndarray | None = None) -> fcl.CollisionObject:
    """The exact triangle mesh ((v, 3) vertices [m], (f, 3) faces) as an fcl
    BVH, placed at ``pose`` (4, 4) (identity by default)."""
    model = fcl.BVHModel()
    model.beginModel(len(vertices), len(faces))
    model.addSubModel(np.asarray(vertices, float), np.asarray(faces, np.int64))
    model.endModel()
    out = fcl.CollisionObject(model, fcl.Transform())
    if pose is not None:
        place(out, pose)
    return out


def place(obj: fcl.CollisionObject, pose: np.ndarray) -> None:
    """Put an fcl object at the (4, 4) world pose ``pose``."""
    obj.setTransform(fcl.Transform(pose[:3, :3], pose[:3, 3]))


def box(half_extents: Sequence[float], pose: np.ndarray) -> fcl.CollisionObject:
    """A box with ``half_extents`` [m] at ``pose``."""
    out = fcl.CollisionObject(fcl.Box(*(2.0 * np.asarray(half_extents, float))), fcl.Transform())
    place(out, pose)
    return out


def collides(a: fcl.CollisionObject, b: fcl.CollisionObject) -> bool:
    """True when the two objects overlap (touching counts)."""
    return bool(fcl.collide(a, b, fcl.CollisionRequest(), fcl.CollisionResult()))


@cache
def _hull(path: str, scale: tuple[float, float, float]) -> fcl.Convex:
    hull = trimesh.load(path, force="mesh").convex_hull
    vertices = np.asarray(hull.vertices, float) * np.asarray(scale, float)
    faces = np.hstack([np.full((len(hull.faces), 1), 3), hull.faces]).ravel()
    return fcl.Convex(vertices, len(hull.faces), faces)


def _geometry(collision: object, folder: Path) -> fcl.CollisionGeometry:
    geometry = collision.geometry  # type: ignore[attr-defined]
    if geometry.mesh is not None:
        path = Path(geometry.mesh.filename.replace("file://", ""))
        path = path if path.is_absolute() else folder / path
        scale = geometry.mesh.scale
        scale = (1.0, 1.0, 1.0) if scale is None else tuple(np.broadcast_to(np.asarray(scale, float), 3))
        return _hull(str(path), scale)
    if geometry.box is not None:
        return fcl.Box(*np.asarray(geometry.box.size, float))
    if geometry.cylinder is not None:
        return fcl.Cylinder(float(geometry.cylinder.radius), float(geometry.cylinder.length))
    if geometry.sphere is not None:
        return fcl.Sphere(float(geometry.sphere.radius))
    raise ConfigError(f"{folder}: a <collision> element with no geometry python-fcl can model")


class LinkShapes:
    """An fcl mirror of some links of a PyBullet body: one fcl object per
    URDF ``<collision>`` element, moved to where PyBullet has its link by
    :meth:`update`."""

    def __init__(self, sim: Sim, body: Body, urdf: Path, links: Sequence[str]) -> None:
        self.sim, self.body = sim, body
        model = load_model(urdf)
        # (link index, (4, 4) collision origin in the link frame, fcl object)
        self.shapes: list[tuple[int, np.ndarray, fcl.CollisionObject]] = []
        for name in links:
            for collision in model.link_map[name].collisions:
                origin = np.eye(4) if collision.origin is None else np.asarray(collision.origin, float)
                shape = fcl.CollisionObject(_geometry(collision, urdf.parent), fcl.Transform())
                self.shapes.append((body.links[name], origin, shape))
        self._moving = sorted({i for i, _, _ in self.shapes if i >= 0})
        self._base = next((n for n, i in body.links.items() if i == -1), None) if any(
            i < 0 for i, _, _ in self.shapes) else None
        self._request = fcl.CollisionRequest()
        self._distance = fcl.DistanceRequest()

    def update(self) -> None:
        """Place every shape where PyBullet has its link now."""
        for (_, _, obj), frame in zip(self.shapes, self.frames()):
            place(obj, frame)

    def frames(self) -> list[np.ndarray]:
        """(4, 4) world pose of every shape where PyBullet has its link now."""
        c = self.sim.client
        frames: dict[int, np.ndarray] = {}
        if self._moving:
            states = pb.getLinkStates(self.body.uid, self._moving, computeForwardKinematics=True, physicsClientId=c)
            frames = {i: pb_to_pose(s[4], s[5]) for i, s in zip(self._moving, states)}
        if self._base is not None:
            frames[-1] = self.sim.link_pose(self.body, self._base)
        return [frames[index] @ origin for index, origin, _ in self.shapes]

    def collides_at(self, pose: np.ndarray, relative: list[np.ndarray], other: fcl.CollisionObject) -> bool:
        """With the body's base at ``pose`` (4, 4) and each shape at
        ``relative`` (its (4, 4) pose in the base frame, from :meth:`frames`
        with the base at the origin): does any shape overlap ``other``? No
        simulator call: candidates sharing a joint configuration share it."""
        request = self._request
        for (_, _, obj), rel in zip(self.shapes, relative):
            place(obj, pose @ rel)
            if fcl.collide(obj, other, request, fcl.CollisionResult()):
                return True
        return False

    def collides(self, other: fcl.CollisionObject) -> bool:
        """True when any shape overlaps ``other`` (early exit)."""
        request = self._request
        return any(fcl.collide(obj, other, request, fcl.CollisionResult()) for _, _, obj in self.shapes)

    def distance(self, other: fcl.CollisionObject) -> float:
        """Smallest true distance [m] from any shape to the BVH ``other``;
        <= 0 when they overlap (python-fcl gives no depth for BVH pairs)."""
        request = self._distance
        return min(fcl.distance(other, obj, request, fcl.DistanceResult()) for _, _, obj in self.shapes)


def _convex(collision: object, folder: Path) -> fcl.Convex:
    """A ``<collision>`` element as one convex shape: a mesh as its hull (as :func:`_geometry`), a primitive as
    the hull of its mesh (a cylinder 32-sided, as PyBullet collides it)."""
    geometry = collision.geometry  # type: ignore[attr-defined]
    if geometry.mesh is not None:
        shape = _geometry(collision, folder)
        assert isinstance(shape, fcl.Convex)
        return shape
    if geometry.box is not None:
        mesh = trimesh.creation.box(extents=np.asarray(geometry.box.size, float))
    elif geometry.cylinder is not None:
        mesh = trimesh.creation.cylinder(float(geometry.cylinder.radius), float(geometry.cylinder.length),
                                         sections=32)
    elif geometry.sphere is not None:
        mesh = trimesh.creation.icosphere(3, float(geometry.sphere.radius))
    else:
        raise ConfigError(f"{folder}: a <collision> element with no geometry python-fcl can model")
    faces = np.hstack([np.full((len(mesh.faces), 1), 3), mesh.faces]).ravel()
    return fcl.Convex(np.asarray(mesh.vertices, float), len(mesh.faces), faces)


class LinkGap:
    """The signed gap [m] between the collision shapes of two links ``a`` and
    ``b`` of a URDF, each link placed by its (4, 4) frame: the least distance
    between a shape of one and a shape of the other, negative where they
    overlap (minus the depth). Each ``<collision>`` element is a convex
    shape (:func:`_convex`) with no margin: the true geometry."""

    def __init__(self, urdf: Path, a: str, b: str) -> None:
        model = load_model(urdf)

        def shapes(link: str) -> list[tuple[np.ndarray, fcl.CollisionObject]]:
            return [(np.eye(4) if c.origin is None else np.asarray(c.origin, float),
                     fcl.CollisionObject(_convex(c, urdf.parent), fcl.Transform()))
                    for c in model.link_map[link].collisions]

        self.a, self.b = shapes(a), shapes(b)
        if not self.a or not self.b:
            raise ConfigError(f"{urdf}: links '{a}' and '{b}' need collision shapes to measure the gap between them")
        self._request = fcl.DistanceRequest(enable_signed_distance=True)

    def __call__(self, frame_a: np.ndarray, frame_b: np.ndarray) -> float:
        """[m] the signed gap with link ``a`` at ``frame_a`` (4, 4) and link ``b`` at ``frame_b`` (4, 4), one frame."""
        for frame, shapes in ((frame_a, self.a), (frame_b, self.b)):
            for origin, obj in shapes:
                place(obj, frame @ origin)
        return float(min(fcl.distance(x, y, self._request, fcl.DistanceResult())
                         for _, x in self.a for _, y in self.b))
