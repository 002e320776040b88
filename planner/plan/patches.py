"""Contact patches: where a hand link's surface meets the object, discretised
into point contacts (grasping-foundations sec. 2.2: larger contact areas are
discretised into point contacts; a small one is a soft finger).

Per grasp, for each link that touches (object frame; the surfaces of steps 1
and 2: :mod:`planner.plan.patch_surfaces`):

1. The link's collision surface is sampled once per hand, in the link frame,
   about one sample per ``spacing``^2 (area-weighted, seeded); meshes are
   replaced by their convex hull, as PyBullet collides them.
2. The samples are moved by the link's pose and their signed gap to the
   object's triangle mesh is computed: exact closest points (an AABB tree of
   the mesh, :mod:`planner.geometry.distance`), first for cells of samples
   to skip those far from the object.
3. The link's patch is its samples within ``depth`` of its own smallest gap
   (closing stops each link a fraction of a millimetre short; a pad pressed
   on the object flattens by about as much).
4. The patch splits into regions: neighbours closer than ``link_radius``
   whose contact normals differ by less than ``split_angle`` (a finger
   wrapped over an edge touches two faces: two regions). A region whose own
   smallest gap is more than ``touch`` above its link's does not touch.
5. A region narrower than ``small`` stays ONE soft-finger contact at its
   centre with the radius sqrt(area / pi) of a disc of its area (its torsion,
   2/3 mu radius, follows in :func:`planner.plan.contacts.contact_models`);
   a larger region gives up
   to ``max_points`` point contacts with friction at the extreme points of the
   region in its tangent plane (a rectangle: its corners).

Normals come from the surface that is smooth at the contact: the object's
face normal inside a face or on an edge whose faces meet at less than
``sharp_angle``; the link's own normal where the object has a sharp edge or
corner there (a box edge pressed into a pad), or the nearest normal the
object has there when the link's is not one of them (a link's side or rim
on an edge: :meth:`ObjectSurface.contact_normals`). Contact points lie on
the object. Everything downstream (G, epsilon, forces) takes these contacts
unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from planner.geometry.frames import tangent_bases
from planner.plan.patch_surfaces import (
    BOUND,
    SLACK,
    LinkSurface,
    ObjectSurface,
    PatchSettings,
    collision_mesh,
    hand_surfaces,
)
from planner.record.contacts import HandContacts
from planner.specs.hands import HandSpec

__all__ = ["BOX_MARGIN", "ObjectSurface", "PatchSettings", "Region", "collision_mesh", "discretise", "extreme_points",
           "hand_surfaces", "link_regions", "regions"]

#: [m] how far outside the object's bounding box a link sample is still
#: measured (a touching link's band lies within depth + prefilter of the
#: surface, its smallest gap within closing's contact tolerance: 3 mm is ample;
#: speed only).
BOX_MARGIN = 0.003


@dataclass(frozen=True)
class Region:
    """One contact region of one link, object frame.

    points : (k, 3) closest points on the object [m]; normals : (k, 3) contact
    normals into the object; area [m^2]; diameter [m], its largest width in
    the tangent plane; normal : (3,) mean contact normal.
    """

    link: str
    points: np.ndarray
    normals: np.ndarray
    area: float
    diameter: float
    normal: np.ndarray


# -- regions ----------------------------------------------------------------------

def link_regions(link: str, surface: LinkSurface, pose: np.ndarray, obj: ObjectSurface) -> list[Region]:
    """The contact regions of one link at ``pose`` (4, 4), link frame in the object frame."""
    s = obj.settings
    lo, hi = obj.mesh.bounds
    points = surface.points @ pose[:3, :3].T + pose[:3, 3]
    within = (points > lo - BOX_MARGIN) & (points < hi + BOX_MARGIN)
    idx = np.flatnonzero(within[:, 0] & within[:, 1] & within[:, 2])  # np.all(axis=1), at half the cost
    if len(idx) == 0:
        return []
    idx, nearest = _band(surface, pose, points, idx, obj)
    if len(idx) == 0:
        return []
    weight = 1.0
    if len(idx) > s.max_exact:  # a large flat patch: a seeded subsample keeps its shape and area
        weight = len(idx) / s.max_exact
        at = np.searchsorted(idx, np.sort(np.random.default_rng(s.seed).choice(idx, s.max_exact, replace=False)))
        idx, nearest = idx[at], tuple(a[at] for a in nearest)
    closest, gap, _, smooth = obj.signed(points[idx], *nearest)
    floor = max(float(gap.min()), 0.0)
    keep = gap <= floor + s.depth
    idx, closest, gap, smooth, face = idx[keep], closest[keep], gap[keep], smooth[keep], nearest[2][keep]
    normals = obj.contact_normals(closest, face, smooth, surface.normals[idx] @ pose[:3, :3].T)
    # the whole band: its neighbours from the link's own pairs; a subsample: its own, farther apart
    pairs = surface.pairs_among(idx, s.link_radius) if weight == 1.0 else None
    labels = _cluster(points[idx], normals, s.link_radius * np.sqrt(weight), s.split_angle, pairs)
    out = []
    for label in np.unique(labels):
        sel = labels == label
        if gap[sel].min() > floor + s.touch:
            continue  # the fringe around a nearby feature, not touching
        mean = normals[sel].mean(axis=0)
        mean /= np.linalg.norm(mean)
        out.append(Region(link, closest[sel], normals[sel], weight * float(surface.area[idx[sel]].sum()),
                          _diameter(closest[sel], mean), mean))
    return out


def _band(surface: LinkSurface, pose: np.ndarray, points: np.ndarray, idx: np.ndarray,
          obj: ObjectSurface) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The samples ``idx`` (ascending) whose distance to the object is
    within depth + prefilter of the smallest distance of them all (none
    when none is within ``BOUND``), and their :meth:`ObjectSurface.nearest`.

    The same samples as measuring each of them (:func:`_band_reference`),
    but cells of the link's samples bound whole groups first (triangle
    inequality: a sample's distance is its cell centre's within the cell's
    radius, and the centre's is bounded by the object's grid of exact
    distances, :meth:`ObjectSurface.bounds`, without a tree search): the
    smallest distance is at most the least upper bound of a cell, so only
    the cells whose lower bound is within depth + prefilter of that can hold
    samples of the band, and only their samples are measured exactly.
    """
    s = obj.settings
    cells = surface.cells
    none = idx[:0], (np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int64))
    if len(idx) == 0:
        return none
    inside = np.zeros(len(points), bool)
    inside[idx] = True
    chosen = np.flatnonzero(np.bincount(cells.cell[idx], minlength=len(cells.centres)))
    lower, upper = cells.reach(chosen, pose, obj)
    if not np.isfinite(upper).any():
        return none
    maybe = cells.members(chosen[lower <= upper.min() + s.depth + s.prefilter + SLACK], inside)
    closest, distance, face = obj.nearest(points[maybe])
    if distance.min() > BOUND:
        return none
    keep = (distance <= distance.min() + s.depth + s.prefilter) & (distance <= BOUND)
    return maybe[keep], (closest[keep], distance[keep], face[keep])


def _band_reference(points: np.ndarray, idx: np.ndarray, obj: ObjectSurface) -> np.ndarray:
    """:func:`_band` the plain way: every sample's distance."""
    s = obj.settings
    bound = obj.distance(points[idx], BOUND)
    if not np.isfinite(bound).any():
        return idx[:0]
    return idx[bound <= bound.min() + s.depth + s.prefilter]


def _cluster(points: np.ndarray, normals: np.ndarray, radius: float, split_angle: float,
             pairs: np.ndarray | None = None) -> np.ndarray:
    """(k,) labels: connected components of samples closer than ``radius``
    whose normals differ by less than ``split_angle``; ``pairs`` (p, 2):
    the pairs closer than ``radius`` when already known, ascending by their
    first sample (:meth:`LinkSurface.pairs_among`)."""
    known = pairs is not None
    if pairs is None:
        pairs = cKDTree(points).query_pairs(radius, output_type="ndarray") if len(points) > 1 else np.zeros((0, 2), int)
    if len(pairs):  # take and compress: a third of the time of fancy indexing and a boolean mask
        first, second = pairs.T
        similar = np.einsum("ij,ij->i", normals.take(first, axis=0), normals.take(second, axis=0)) > np.cos(split_angle)
        pairs = pairs.compress(similar, axis=0)
    if not known:  # the graph's rows; their order within a row changes no label (numbered by smallest member)
        pairs = pairs[np.argsort(pairs[:, 0])]
    n = len(points)
    graph = csr_matrix((np.ones(len(pairs)), pairs[:, 1], np.searchsorted(pairs[:, 0], np.arange(n + 1))), shape=(n, n))
    return connected_components(graph, directed=False)[1]


def _plane(points: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """(k, 2) coordinates in the tangent plane through the points' centroid."""
    l_vec, o_vec = (v[0] for v in tangent_bases(normal[None]))
    rel = points - points.mean(axis=0)
    return np.column_stack([rel @ l_vec, rel @ o_vec])


#: 32 directions of projection (half a turn): the extreme points along them
#: are the 2-D hull's vertices to ~3 degrees, widths within 0.5%, without
#: qhull's set-up cost.
_DIRS = np.stack([np.cos(np.arange(32) * np.pi / 32), np.sin(np.arange(32) * np.pi / 32)], axis=1)


def _diameter(points: np.ndarray, normal: np.ndarray) -> float:
    """Largest width [m] of the region in its tangent plane."""
    if len(points) < 2:
        return 0.0
    proj = _plane(points, normal) @ _DIRS.T
    return float(np.max(proj.max(axis=0) - proj.min(axis=0)))


def extreme_points(points: np.ndarray, normal: np.ndarray, limit: int) -> np.ndarray:
    """Indices of up to ``limit`` extreme points of a region in its tangent
    plane, in farthest-point order from the one farthest from the centroid
    (a rectangle gives its corners)."""
    uv = _plane(points, normal)
    proj = uv @ _DIRS.T
    hull = np.unique(np.r_[np.argmax(proj, axis=0), np.argmin(proj, axis=0)])
    v = uv[hull]
    chosen = [int(np.argmax(np.linalg.norm(v, axis=1)))]
    dist = np.linalg.norm(v - v[chosen[0]], axis=1)
    while len(chosen) < min(limit, len(v)):
        k = int(np.argmax(dist))
        if dist[k] <= 1e-9:
            break
        chosen.append(k)
        dist = np.minimum(dist, np.linalg.norm(v - v[k], axis=1))
    return hull[chosen]


def regions(hand: HandSpec, obj: ObjectSurface, link_poses: dict[str, np.ndarray],
            links: tuple[str, ...]) -> list[Region]:
    """Contact regions of the given (touching) links; ``link_poses`` (4, 4) in the object frame."""
    surfaces = hand_surfaces(hand, obj.settings)
    out: list[Region] = []
    for link in links:
        if link in surfaces:
            out += link_regions(link, surfaces[link], link_poses[link], obj)
    return out


def discretise(found: list[Region], settings: PatchSettings) -> HandContacts:
    """Point contacts at the extreme points of large regions, one soft-finger
    contact at the centre of each small one (see the module docstring)."""
    points, normals, links, radius, owner = [], [], [], [], []
    for r_i, r in enumerate(found):
        if r.diameter < settings.small:
            points.append(r.points[int(np.argmin(np.linalg.norm(r.points - r.points.mean(axis=0), axis=1)))])
            normals.append(r.normal)
            radius.append(float(np.sqrt(r.area / np.pi)))
            links.append(r.link)
            owner.append(r_i)
            continue
        for k in extreme_points(r.points, r.normal, settings.max_points):
            points.append(r.points[k])
            normals.append(r.normals[k] / np.linalg.norm(r.normals[k]))
            radius.append(0.0)
            links.append(r.link)
            owner.append(r_i)
    return HandContacts(np.array(points, float).reshape(-1, 3), np.array(normals, float).reshape(-1, 3),
                        tuple(links), np.array(radius, float), np.array(owner, int))
