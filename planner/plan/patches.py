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

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from planner.geometry.frames import tangent_bases
from planner.plan.patch_clusters import by_node as _by_node  # noqa: F401 - the clusters' helpers under their
from planner.plan.patch_clusters import cluster as _cluster  # names before they moved (tests read them here)
from planner.plan.patch_clusters import components as _components  # noqa: F401
from planner.plan.patch_clusters import components_reference as _components_reference  # noqa: F401
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
    the tangent plane; normal : (3,) mean contact normal; plane : (k, 2) [m]
    the points' coordinates in the tangent plane (:func:`_plane`), which its
    diameter was measured from (None: not kept); :func:`extreme_points` reads
    them instead of projecting the points a second time.
    """

    link: str
    points: np.ndarray
    normals: np.ndarray
    area: float
    diameter: float
    normal: np.ndarray
    plane: np.ndarray | None = field(default=None, compare=False, repr=False)


# -- regions ----------------------------------------------------------------------

def link_regions(link: str, surface: LinkSurface, pose: np.ndarray, obj: ObjectSurface) -> list[Region]:
    """The contact regions of one link at ``pose`` (4, 4), link frame in the object frame."""
    s = obj.settings
    lo, hi = obj.mesh.bounds
    points = surface.points @ pose[:3, :3].T + pose[:3, 3]
    idx = _in_box(points, lo - BOX_MARGIN, hi + BOX_MARGIN)
    if len(idx) == 0:
        return []
    idx, nearest = _band(surface, pose, points, idx, obj)
    if len(idx) == 0:
        return []
    idx, nearest, weight = _subsample(idx, nearest, s)
    closest, gap, _, smooth, feature = obj.signed_features(points[idx], *nearest)
    floor = max(float(gap.min()), 0.0)
    keep = gap <= floor + s.depth
    idx, closest, gap, smooth, face = idx[keep], closest[keep], gap[keep], smooth[keep], nearest[2][keep]
    normals = obj.contact_normals(closest, face, smooth, surface.normals[idx] @ pose[:3, :3].T, feature.take(keep))
    return _link_regions(link, surface, points, idx, weight, closest, gap, floor, normals, s)


def _in_box(points: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """(n,) ascending indices of the ``points`` (k, 3) strictly inside the box ``low``..``high`` (3,): a coordinate
    at a time against a number (comparing (k, 3) with (3,) runs numpy's inner loop over 3 elements: 4x the time)."""
    x, y, z = points.T
    inside = (x > low[0]) & (x < high[0])
    inside &= y > low[1]
    inside &= y < high[1]
    inside &= z > low[2]
    inside &= z < high[2]
    return np.flatnonzero(inside)


def _subsample(idx: np.ndarray, nearest: tuple[np.ndarray, ...], s: PatchSettings
               ) -> tuple[np.ndarray, tuple[np.ndarray, ...], float]:
    """(samples, their nearest, weight): a band ``idx`` (ascending) of more than ``max_exact`` samples, a large flat
    patch, as a seeded subsample that keeps its shape and area, each standing for ``weight`` samples."""
    if len(idx) <= s.max_exact:
        return idx, nearest, 1.0
    at = _subsample_at(s.seed, len(idx), s.max_exact)
    return idx[at], tuple(a[at] for a in nearest), len(idx) / s.max_exact


@lru_cache(maxsize=1024)
def _subsample_at(seed: int, n: int, size: int) -> np.ndarray:
    """(size,) ascending positions of a seeded subsample of n: those ``default_rng(seed).choice(idx, size,
    replace=False)`` takes of any ascending ``idx`` (n,) (its positions depend on n alone), once per n (a flat
    face's bands repeat their sizes); read-only."""
    at = np.sort(np.random.default_rng(seed).choice(n, size, replace=False))
    at.flags.writeable = False
    return at


def _link_regions(link: str, surface: LinkSurface, points: np.ndarray, idx: np.ndarray, weight: float,
                  closest: np.ndarray, gap: np.ndarray, floor: float, normals: np.ndarray,
                  s: PatchSettings) -> list[Region]:
    """One link's regions from its patch: samples ``idx`` (ascending) of its ``points`` (k, 3) (object frame),
    their ``closest`` points, signed ``gap`` and contact ``normals``, the link's smallest gap ``floor``."""
    # the whole band: its neighbours from the link's own pairs; a subsample: its own, farther apart
    pairs = surface.pairs_among(idx, s.link_radius) if weight == 1.0 else None
    labels = _cluster(points[idx], normals, s.link_radius * np.sqrt(weight), s.split_angle, pairs)
    out = []
    if len(labels) and not labels.any():  # one region (labels count from 0): every sample, without masks
        return [] if gap.min() > floor + s.touch else [_region(link, closest, normals, weight * float(
            surface.area[idx].sum()))]
    for label in np.unique(labels):
        sel = labels == label
        if gap[sel].min() > floor + s.touch:
            continue  # the fringe around a nearby feature, not touching
        out.append(_region(link, closest[sel], normals[sel], weight * float(surface.area[idx[sel]].sum())))
    return out


def _region(link: str, points: np.ndarray, normals: np.ndarray, area: float) -> Region:
    """The :class:`Region` of ``points`` (k, 3) with contact ``normals`` (k, 3) and ``area`` [m^2]."""
    mean = normals.mean(axis=0)
    mean /= np.linalg.norm(mean)
    uv = _plane(points, mean) if len(points) >= 2 else None
    return Region(link, points, normals, area, _width(uv), mean, uv)


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


def _plane(points: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """(k, 2) coordinates in the tangent plane through the points' centroid."""
    l_vec, o_vec = (v[0] for v in tangent_bases(normal[None]))
    rel = points - points.mean(axis=0)
    return np.column_stack([rel @ l_vec, rel @ o_vec])


#: 32 directions of projection (half a turn): the extreme points along them
#: are the 2-D hull's vertices to ~3 degrees, widths within 0.5%, without
#: qhull's set-up cost.
_DIRS = np.stack([np.cos(np.arange(32) * np.pi / 32), np.sin(np.arange(32) * np.pi / 32)], axis=1)


def _width(uv: np.ndarray | None) -> float:
    """Largest width [m] of points given by their tangent-plane coordinates ``uv`` (k, 2) (None: fewer than
    two points, 0)."""
    if uv is None:
        return 0.0
    proj = uv @ _DIRS.T
    return float(np.max(proj.max(axis=0) - proj.min(axis=0)))


def extreme_points(points: np.ndarray, normal: np.ndarray, limit: int, plane: np.ndarray | None = None
                   ) -> np.ndarray:
    """Indices of up to ``limit`` extreme points of a region in its tangent
    plane, in farthest-point order from the one farthest from the centroid
    (a rectangle gives its corners); ``plane`` (k, 2): the points'
    :func:`_plane` coordinates, when already known (:attr:`Region.plane`)."""
    uv = _plane(points, normal) if plane is None else plane
    proj = uv @ _DIRS.T
    hull = np.unique(np.r_[np.argmax(proj, axis=0), np.argmin(proj, axis=0)])
    v = uv[hull]
    chosen = [int(np.argmax(_norms(v)))]
    dist = _norms(v - v[chosen[0]])
    while len(chosen) < min(limit, len(v)):
        k = int(np.argmax(dist))
        if dist[k] <= 1e-9:
            break
        chosen.append(k)
        dist = np.minimum(dist, _norms(v - v[k]))
    return hull[chosen]


def _norms(v: np.ndarray) -> np.ndarray:
    """(h,) lengths of the rows of ``v`` (h, 2): ``np.linalg.norm(v, axis=1)`` to the bit (the same two squares
    and one sum), without its set-up."""
    return np.sqrt(v[:, 0] * v[:, 0] + v[:, 1] * v[:, 1])


def regions(hand: HandSpec, obj: ObjectSurface, link_poses: dict[str, np.ndarray],
            links: tuple[str, ...]) -> list[Region]:
    """Contact regions of the given (touching) links; ``link_poses`` (4, 4) in the object frame: each link's
    :func:`link_regions`, in the order of ``links``, the links' object queries made together (:func:`_together`)."""
    surfaces = hand_surfaces(hand, obj.settings)
    return _together([(link, surfaces[link], link_poses[link]) for link in links if link in surfaces], obj)


def _together(links: list[tuple[str, LinkSurface, np.ndarray]], obj: ObjectSurface) -> list[Region]:
    """The :func:`link_regions` of each (link, surface, pose) of ``links``, concatenated, bit for bit: every
    object query of theirs (the grid's distance bounds, the exact closest points, the signed gaps, the closest
    points' features and the contact normals) answers each row from that row alone, so the links' rows go in one
    call each instead of one per link (a Panda grasp's two fingers: half the calls, 7-10% of the patches' CPU on
    captured units); the features only of the samples within ``depth`` (the patch), not of the whole band; the
    exact closest points only of the samples whose own bound may lie in the band (:func:`_bounded`). Each
    link's matrix products (its pose applied to its samples, cells and normals) keep their shapes: a product's
    rows are BLAS's bits for that shape (one row takes another kernel)."""
    s = obj.settings
    lo, hi = obj.mesh.bounds
    placed = []  # (link, surface, pose, points (k, 3), in-box samples, their cells)
    for link, surface, pose in links:
        points = surface.points @ pose[:3, :3].T + pose[:3, 3]
        idx = _in_box(points, lo - BOX_MARGIN, hi + BOX_MARGIN)
        if len(idx):
            chosen = np.flatnonzero(np.bincount(surface.cells.cell[idx], minlength=len(surface.cells.centres)))
            placed.append((link, surface, pose, points, idx, chosen))
    if not placed:
        return []
    centres = [p[1].cells.placed(p[5], p[2]) for p in placed]
    lower, upper = _split(obj.bounds(np.concatenate(centres)), centres)
    maybe = []  # (link, surface, pose, points, samples to measure)
    for (link, surface, pose, points, idx, chosen), low, up in zip(placed, lower, upper):
        low, up = surface.cells.widen(chosen, low, up)
        if np.isfinite(up).any():
            inside = np.zeros(len(points), bool)
            inside[idx] = True
            maybe.append((link, surface, pose, points,
                          surface.cells.members(chosen[low <= up.min() + s.depth + s.prefilter + SLACK], inside)))
    if not maybe:
        return []
    asked = [m[3][m[4]] for m in maybe]
    maybe, asked = _bounded(maybe, asked, obj)
    banded = []  # (link, surface, pose, points, band samples, weight, their closest points, distances, faces)
    for (link, surface, pose, points, idx), closest, distance, face in zip(maybe, *_split(
            obj.nearest(np.concatenate(asked)), asked)):
        if distance.min() > BOUND:
            continue
        keep = (distance <= distance.min() + s.depth + s.prefilter) & (distance <= BOUND)
        idx, nearest, weight = _subsample(idx[keep], (closest[keep], distance[keep], face[keep]), s)
        banded.append((link, surface, pose, points, idx, weight, *nearest))
    if not banded:
        return []
    rows = [b[3][b[4]] for b in banded]
    gaps = _split((obj.gaps(np.concatenate(rows), *(np.concatenate([b[k] for b in banded]) for k in (6, 7, 8))),),
                  rows)[0]
    patch = []  # (link, surface, pose, points, patch samples, weight, closest points, faces, gaps, floor)
    for (link, surface, pose, points, idx, weight, closest, _, face), gap in zip(banded, gaps):
        floor = max(float(gap.min()), 0.0)
        keep = gap <= floor + s.depth
        patch.append((link, surface, pose, points, idx[keep], weight, closest[keep], face[keep], gap[keep], floor))
    closest, face = (np.concatenate([p[k] for p in patch]) for k in (6, 7))
    feature, smooth = obj.features(closest, face)
    toward = np.concatenate([p[1].normals[p[4]] @ p[2][:3, :3].T for p in patch])
    normals = _split((obj.contact_normals(closest, face, smooth, toward, feature),), [p[4] for p in patch])[0]
    out: list[Region] = []
    for (link, surface, _, points, idx, weight, closest, _, gap, floor), normal in zip(patch, normals):
        out += _link_regions(link, surface, points, idx, weight, closest, gap, floor, normal, s)
    return out


def _bounded(maybe: list[tuple], asked: list[np.ndarray], obj: ObjectSurface) -> tuple[list[tuple], list[np.ndarray]]:
    """Of each link's samples to measure (``maybe``: (link, surface, pose, points, samples); ``asked``: their points
    (k, 3)), those whose own lower distance bound (:meth:`ObjectSurface.bounds`, the grid's without a cell's radius)
    is within depth + prefilter of the least upper bound among them, and their points: the samples of the band and
    the nearest of them all are among them (triangle inequality, as :func:`_band`), so the band is the same, for
    fewer exact queries (a tree search costs 2-3 us a point on a mesh of hundreds of faces, a look-up well under
    one: a fifth to a third fewer points on the mug and random_002; on the box's 12 faces about even)."""
    s = obj.settings
    kept_maybe, kept_asked = [], []
    for (link, surface, pose, points, idx), rows, lower, upper in zip(maybe, asked, *_split(
            obj.bounds(np.concatenate(asked)), asked)):
        near = lower <= upper.min() + s.depth + s.prefilter + 2 * SLACK
        kept_maybe.append((link, surface, pose, points, idx[near]))
        kept_asked.append(rows[near])
    return kept_maybe, kept_asked


def _split(arrays: tuple[np.ndarray, ...], parts: list[np.ndarray]) -> list[list[np.ndarray]]:
    """Each of ``arrays`` (n, ...) cut in the lengths of ``parts`` (n in all): ``out[k][i]``, array k's rows of part
    i (a query made for the parts together, split back), views as ``np.split`` gives them, by slices (its set-up
    costs more than the cut of a grasp's two or three parts)."""
    ends = [0]
    for part in parts:
        ends.append(ends[-1] + len(part))
    return [[a[i:j] for i, j in zip(ends[:-1], ends[1:])] for a in arrays]


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
        for k in extreme_points(r.points, r.normal, settings.max_points, r.plane):
            points.append(r.points[k])
            normals.append(r.normals[k] / np.linalg.norm(r.normals[k]))
            radius.append(0.0)
            links.append(r.link)
            owner.append(r_i)
    return HandContacts(np.array(points, float).reshape(-1, 3), np.array(normals, float).reshape(-1, 3),
                        tuple(links), np.array(radius, float), np.array(owner, int))
