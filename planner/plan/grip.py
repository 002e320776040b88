"""Grip geometry: how the object sits between the fingers of a closed grasp
(issue 26).

The analytic measures (:mod:`planner.plan.measures`) judge the contacts
closing found; what decides whether a grasp survives a shake is also the
surface *around* them: how much of the object a pad could press on, how
square that surface is to the pad, how much of the object lies between the
fingers, how deep the object sits in the hand. Measured against ACRONYM's
FleX labels on the tuning objects (bench/RESULTS.md), these carry most of
what the contacts alone miss. Each is computed from evenly spaced samples of
the object's surface (:class:`GripSurface`, ~1 per ``spacing``^2) and each
link's convex collision hull at the closed configuration (PyBullet collides
meshes as their hulls):

* ``pad_area`` [m^2]: for each finger that touches (a finger: a chain of
  links, :attr:`~planner.specs.hands.HandSpec.fingers`), the object surface
  within ``band`` of its links' hulls and facing them; the smallest over
  the touching fingers. A pad on a flat face: its whole face; on an edge
  or a thin rim: a sliver.
* ``pad_alignment``: over the same surface, the area-weighted mean cosine
  between the object's inward normal and the facing hull face's outward
  normal (1: the surface lies flat on the pad); the smallest over fingers.
* ``opposition``: the largest, over pairs of touching fingers, of
  ``-n_i . n_j`` of their pad surfaces' mean inward normals (1: the two
  pads press straight against each other).
* ``jaw_fill`` [m^2]: the object surface inside the convex hull of the
  touching fingers' hulls: the faces under the pads and whatever else lies
  between them (the far walls of a hollow body, a handle, a second part).
* ``com_lever`` [m]: the distance from the object's centre of mass to the
  line through the pad centres (area-weighted) of the best-opposed pair of
  touching fingers: the lever its weight and a shake have about the grip's
  axis, which only the pads' friction over their area resists.
* ``com_height`` [m]: the height of the centre of mass above the midpoint
  of those two pad centres, along the object's up as it rests (its own,
  ``PreparedObject.up``: the object frame's +z unless told; on a table, the table's
  up, :func:`~planner.geometry.frames.resting_up`): negative where the object hangs
  below the grip (it swings back under a shake), positive where it stands
  on it (it tips over).
* ``gravity_arm`` [m]: the lever the object's weight has about that grip
  axis when the object hangs as it rests (weight along -up): the distance
  from the axis to the centre of mass, across both the axis and the
  vertical; 0 when the axis is vertical or runs over the centre of mass.
* ``palm_gap`` [m]: the smallest distance from the object surface inside
  that hull (between the fingers) to the root link's (palm's) hull, at most
  ``palm_reach``: how deep the object sits in the hand.

Frames: everything in the object frame; hull faces are given per link in
the link frame and moved by the link poses closing reports.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
import trimesh
from scipy.spatial import ConvexHull, QhullError

from planner.geometry.frames import UP, rows_cross
from planner.plan.link_hulls import Hull, hulls
from planner.plan.link_hulls import planes as _planes
from planner.record.contacts import HandContacts
from planner.specs.hands import HandSpec


@dataclass(frozen=True)
class GripSettings:
    """Lengths in metres."""

    spacing: float = 0.001  # object surface samples, about one per spacing^2
    max_samples: int = 200_000  # a large object gets sparser samples
    band: float = 0.0015  # object surface this close to a finger hull counts as under the pad
    coarse: int = 4  # jaw_fill and palm_gap read every coarse-th sample (2 mm apart at the default spacing)
    palm_reach: float = 0.05  # palm_gap is capped here (the object is not near the palm)
    seed: int = 0


@dataclass(frozen=True)
class Grip:
    """The grip measures of one grasp (see the module docstring); NaN where
    a measure does not apply (``opposition`` with fewer than two fingers
    touching, ``palm_gap`` for a hand whose root link has no collision
    geometry)."""

    pad_area: float
    pad_alignment: float
    opposition: float
    jaw_fill: float
    palm_gap: float
    com_lever: float
    com_height: float
    gravity_arm: float


class GripSurface:
    """Random samples of an object's surface, area-weighted: points (n, 3)
    [m] and outward normals (n, 3), object frame, each standing for ``area``
    [m^2]; kept sorted by x so that a box query is a binary search and a
    mask."""

    def __init__(self, mesh: trimesh.Trimesh, settings: GripSettings | None = None,
                 normals_at: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None) -> None:
        """``normals_at(points, faces)``: the normals at the samples (default:
        their faces'; a scan's at a contact's scale, as its contacts read them)."""
        self.settings = settings or GripSettings()
        s = self.settings
        count = int(min(max(np.ceil(mesh.area / s.spacing**2), 1), s.max_samples))
        points, faces = trimesh.sample.sample_surface(mesh, count, seed=s.seed)
        points = np.asarray(points, float)
        order = np.argsort(points[:, 0], kind="stable")
        self.points = points[order]
        normals = mesh.face_normals[faces] if normals_at is None else normals_at(points, faces)
        self.normals = np.asarray(normals, float)[order]
        self.area = float(mesh.area) / len(self.points)
        coarse = points[::s.coarse]  # every coarse-th draw: a uniform subsample, the same whatever the frame
        self.coarse = coarse[np.argsort(coarse[:, 0], kind="stable")]
        self.coarse_area = float(mesh.area) / len(self.coarse)
        # each coordinate as its own contiguous array: a box query reads a slab of x and tests y and z
        # on the fly (4-5x less work than (m, 2) comparisons over the strided slab and an all())
        self._columns = tuple(np.ascontiguousarray(self.points.T)), tuple(np.ascontiguousarray(self.coarse.T))

    def box(self, lo: np.ndarray, hi: np.ndarray, coarse: bool = False) -> np.ndarray:
        """Indices (ascending) of the samples (of :attr:`coarse` if ``coarse``)
        inside the axis-aligned box ``lo``..``hi`` (3,) [m], bounds included
        but x's upper one (a sample at exactly ``hi[0]`` is left out); the same
        as :meth:`box_reference`."""
        x, y, z = self._columns[int(coarse)]
        a, b = np.searchsorted(x, [lo[0], hi[0]], side="left")
        idx = np.flatnonzero((y[a:b] >= lo[1]) & (y[a:b] <= hi[1]))
        zs = z[a + idx]
        return a + idx[(zs >= lo[2]) & (zs <= hi[2])]

    def box_reference(self, lo: np.ndarray, hi: np.ndarray, coarse: bool = False) -> np.ndarray:
        """:meth:`box` the plain way: the x slab, then every coordinate of it at once."""
        points = self.coarse if coarse else self.points
        a, b = np.searchsorted(points[:, 0], [lo[0], hi[0]], side="left")
        sub = points[a:b, 1:]
        return a + np.flatnonzero(np.all((sub >= lo[1:]) & (sub <= hi[1:]), axis=1))


def measure(hand: HandSpec, surface: GripSurface, contacts: HandContacts,
            link_poses: Mapping[str, np.ndarray], com: np.ndarray, up: np.ndarray = UP) -> Grip:
    """The grip measures of a closed grasp: ``contacts`` say which links touch,
    ``link_poses`` (4, 4) place them (object frame; at least every touching
    contact link and the root link); ``com`` (3,) [m] the object's centre of
    mass; ``up`` (3,) the object's up as it rests, object frame (its own,
    ``PreparedObject.up``, +z unless told; a grasp planned on a table: the
    table's up, :func:`~planner.geometry.frames.resting_up`)."""
    s = surface.settings
    shapes = hulls(hand)
    touching = set(contacts.links)
    fingers = [[link for link in f if link in touching and link in shapes and link in link_poses]
               for f in hand.fingers]
    fingers = [f for f in fingers if f]
    areas, aligns, normals, centres, corners = [], [], [], [], []
    for finger in fingers:
        area, weighted, normal, moment = 0.0, 0.0, np.zeros(3), np.zeros(3)
        for link in finger:
            own = contacts.points[np.array(contacts.links) == link]
            pad = _pad(shapes[link], link_poses[link], surface, s.band, own)
            area, weighted, normal, moment = area + pad.area, weighted + pad.aligned, normal + pad.normal, \
                moment + pad.moment
            corners.append(pad.corners)
        areas.append(area)
        aligns.append(weighted / area if area > 0 else 0.0)
        normals.append(normal / np.linalg.norm(normal) if np.linalg.norm(normal) > 0 else normal)
        centres.append(moment / area if area > 0 else contacts.points[np.isin(contacts.links, finger)].mean(axis=0))
    pairs = [(-float(normals[i] @ normals[j]), i, j) for i in range(len(fingers)) for j in range(i + 1, len(fingers))]
    opposition, a, b = max(pairs, default=(np.nan, 0, 0))
    inside = _inside(np.vstack(corners), surface) if len(fingers) >= 2 else np.zeros(0, int)
    palm = _palm_gap(hand, shapes, link_poses, surface, inside)
    com = np.asarray(com, float)
    lever = _lever(com, centres[a], centres[b]) if pairs else np.nan
    height, arm = _gravity(com, centres[a], centres[b], np.asarray(up, float)) if pairs else (np.nan, np.nan)
    return Grip(pad_area=min(areas, default=0.0), pad_alignment=min(aligns, default=0.0), opposition=opposition,
                jaw_fill=surface.coarse_area * len(inside), palm_gap=palm, com_lever=lever, com_height=height,
                gravity_arm=arm)


def _gravity(com: np.ndarray, a: np.ndarray, b: np.ndarray, up: np.ndarray = UP) -> tuple[float, float]:
    """(height [m] of ``com`` above the midpoint of ``a`` and ``b`` (3,) along the unit ``up``, the lever [m] of
    a weight along -up at ``com`` about the line through ``a`` and ``b``: |((com - mid) x up) . axis|; about the
    vertical through ``a`` if they coincide: the horizontal distance)."""
    rel = com - 0.5 * (a + b)
    across = rows_cross(rel[None], up[None])[0]  # np.cross's products to the bit, without its set-up
    axis = b - a
    length = float(np.linalg.norm(axis))
    arm = float(np.linalg.norm(across)) if length < 1e-9 else abs(float(across @ axis)) / length
    return float(rel @ up), arm


def _lever(com: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """Distance [m] from ``com`` to the line through ``a`` and ``b`` (3,) (to ``a`` if they coincide)."""
    axis = b - a
    length = float(np.linalg.norm(axis))
    rel = com - a
    if length < 1e-9:
        return float(np.linalg.norm(rel))
    return float(np.linalg.norm(rows_cross(rel[None], (axis / length)[None])[0]))


def _near(hull: Hull, pose: np.ndarray, points: np.ndarray, idx: np.ndarray, band: float
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Of ``points[idx]`` (object frame), those whose signed distance to the
    hull at ``pose`` is below ``band`` [m]: (their indices, their signed
    distances, the face each is taken at), as :func:`_distance` gives them.
    Faces are read by blocks and a point farther than ``band`` from one
    face's plane is dropped at once (the signed distance is the largest)."""
    local = (points[idx] - pose[:3, 3]) @ pose[:3, :3]
    best = np.full(len(idx), -np.inf)
    face = np.zeros(len(idx), int)
    for start in range(0, len(hull.normals), _BLOCK):
        plane = local @ hull.normals[start:start + _BLOCK].T - hull.offsets[start:start + _BLOCK]
        at = np.argmax(plane, axis=1)
        value = plane[np.arange(len(local)), at]
        better = value > best  # strictly: the first face of a tie, as argmax over all faces picks
        best, face = np.where(better, value, best), np.where(better, start + at, face)
        keep = best < band
        idx, local, best, face = idx[keep], local[keep], best[keep], face[keep]
        if not len(idx):
            break
    return idx, best, face


def _distance(hull: Hull, pose: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """((k,) signed distance [m] of ``points`` (k, 3), object frame, to the
    hull at ``pose`` (the largest face-plane distance: exact inside, a lower
    bound outside), (k,) the face it is taken at)."""
    local = (points - pose[:3, 3]) @ pose[:3, :3]
    plane = local @ hull.normals.T - hull.offsets
    face = np.argmax(plane, axis=1)
    return plane[np.arange(len(points)), face], face


#: Faces read at once by the early-exit hull tests (a hull of a meshed finger has hundreds).
_BLOCK = 32


@dataclass(frozen=True)
class _Pad:
    """What lies under one link: area [m^2] of the object surface within the
    band of its touching faces and facing them; aligned: that area times its
    mean alignment; normal, moment: (3,) area-weighted sums of its inward
    normals and of its points [m^3], object frame; corners: (v, 3) the
    link hull's vertices, object frame."""

    area: float
    aligned: float
    normal: np.ndarray
    moment: np.ndarray
    corners: np.ndarray


def _pad(hull: Hull, pose: np.ndarray, surface: GripSurface, band: float, contacts: np.ndarray) -> _Pad:
    """The object surface under one link: within ``band`` of the link's
    touching faces (those nearest its ``contacts`` (k, 3), object frame) and
    facing them. Only touching faces count: the object near a finger's back
    or side is not under its pad."""
    corners = hull.vertices @ pose[:3, :3].T + pose[:3, 3]
    idx = surface.box(corners.min(axis=0) - band, corners.max(axis=0) + band)
    idx, dist, face = _near(hull, pose, surface.points, idx, band)
    if not len(idx) or not len(contacts):
        return _Pad(0.0, 0.0, np.zeros(3), np.zeros(3), corners)
    local = (contacts - pose[:3, 3]) @ pose[:3, :3]
    touching = np.zeros(len(hull.normals), bool)  # the faces nearest the contacts
    touching[np.argmax(local @ hull.normals.T - hull.offsets, axis=1)] = True
    face_normal = hull.normals[face] @ pose[:3, :3].T
    cos = -np.einsum("ij,ij->i", surface.normals[idx], face_normal)
    under = (dist < band) & (cos > 0) & touching[face]
    return _Pad(surface.area * float(under.sum()), surface.area * float(cos[under].sum()),
                -surface.area * surface.normals[idx[under]].sum(axis=0),
                surface.area * surface.points[idx[under]].sum(axis=0), corners)


def _inside(points: np.ndarray, surface: GripSurface) -> np.ndarray:
    """Indices (ascending) of the coarse object samples inside the convex hull of ``points`` (k, 3).

    Most samples in the hull's box are inside it and would need every face:
    on a hull of more than :data:`INNER_PLANES` planes (the Barrett's fingers), an inner
    polytope (the hull of the vertices extreme along the 13 axes of
    :data:`_EXTREME_AXES`, a few dozen faces) settles those at least ``INNER_MARGIN`` inside
    it first, which are inside the hull for sure; those as far beyond the vertices' extent along
    a diagonal axis are outside for sure; the rest take every face (the same samples, as the
    margin is far above the round-off). A hull of fewer planes (the Panda's two fingers: 52
    triangles on ~30 planes) takes every face at once: the inner polytope's own hull cost more
    than it saved (0.66 against 0.37-0.47 ms a grasp on the box and the mug).
    """
    try:
        hull = ConvexHull(points)
    except QhullError:  # a flat or degenerate point set: nothing is inside
        return np.zeros(0, int)
    idx = surface.box(points.min(axis=0), points.max(axis=0), coarse=True)
    outer = _planes(hull.equations)
    if len(outer) <= INNER_PLANES:
        return _within(idx, surface.coarse, outer)
    corners = hull.points[hull.vertices]
    reach = corners @ _EXTREME_AXES.T
    try:
        inner = _planes(ConvexHull(corners[np.unique(np.r_[reach.argmax(axis=0), reach.argmin(axis=0)])]).equations)
    except QhullError:  # the extreme vertices span no volume: every sample takes every face
        inner = np.zeros((0, 4))
    if len(inner):
        samples = surface.coarse[idx]
        values = inner[:, :3] @ samples.T  # planes by samples: all() then reduces whole rows at once
        values += inner[:, 3:]
        inside = np.all(values <= -INNER_MARGIN, axis=0)  # sure to be inside
        rest = np.flatnonzero(~inside)
        along, lo, hi = _EXTREME_AXES[3:] @ samples[rest].T, reach[:, 3:].min(axis=0), reach[:, 3:].max(axis=0)
        out = np.any((along > hi[:, None] + INNER_MARGIN) | (along < lo[:, None] - INNER_MARGIN), axis=0)  # sure
        inside[_within(rest[~out], samples, outer)] = True
        return idx[inside]
    return _within(idx, surface.coarse, outer)


def _within(idx: np.ndarray, points: np.ndarray, eq: np.ndarray) -> np.ndarray:
    """Those of ``idx`` whose ``points`` are on the inner side of every plane of ``eq`` (f, 4), order kept."""
    for start in range(0, len(eq), _BLOCK):  # by blocks of faces: a point outside one is dropped at once
        block = eq[start:start + _BLOCK]
        idx = idx[np.all(points[idx] @ block[:, :3].T + block[:, 3] <= 0.0, axis=1)]
        if not len(idx):
            break
    return idx


INNER_MARGIN = 1e-9  #: [m] this far inside the inner polytope (outside the extents): sure, whatever the round-off
#: A hull of at most this many planes tests every sample against every plane (:func:`_inside`; speed only).
INNER_PLANES = 64
#: 13 axes (rows, unit): the coordinate axes, the face and the body diagonals of a cube; the hull's vertices
#: extreme along them (both ways) span the inner polytope of :func:`_inside`.
_EXTREME_AXES = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0], [1, -1, 0], [1, 0, 1], [1, 0, -1], [0, 1, 1],
                   [0, 1, -1], [1, 1, 1], [1, 1, -1], [1, -1, 1], [-1, 1, 1]], float)
_EXTREME_AXES /= np.linalg.norm(_EXTREME_AXES, axis=1, keepdims=True)


def _palm_gap(hand: HandSpec, shapes: Mapping[str, Hull], link_poses: Mapping[str, np.ndarray],
              surface: GripSurface, inside: np.ndarray) -> float:
    """Smallest distance [m] from the object surface ``inside`` (indices of
    coarse samples) the fingers' hull to the root link's hull, at most ``palm_reach``."""
    reach = surface.settings.palm_reach
    if hand.root_link not in shapes or hand.root_link not in link_poses:
        return float("nan")
    if not len(inside):
        return reach
    palm, pose = shapes[hand.root_link], link_poses[hand.root_link]
    points = surface.coarse[inside]
    # the sample nearest the palm's centre bounds the smallest distance: only samples below it are read to the end
    guess = int(np.argmin(np.linalg.norm(points - (palm.centre @ pose[:3, :3].T + pose[:3, 3]), axis=1)))
    bound = min(float(_distance(palm, pose, points[guess:guess + 1])[0][0]), reach)
    _, below, _ = _near(palm, pose, points, np.arange(len(points)), bound)
    return float(np.clip(min(below.min(initial=bound), bound), 0.0, reach))
