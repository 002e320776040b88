"""Contact patches: where a hand link's surface meets the object, discretised
into point contacts (grasping-foundations sec. 2.2: larger contact areas are
discretised into point contacts; a small one is a soft finger).

Per grasp, for each link that touches (object frame):

1. The link's collision surface is sampled once per hand, in the link frame,
   about one sample per ``spacing``^2 (area-weighted, seeded); meshes are
   replaced by their convex hull, as PyBullet collides them.
2. The samples are moved by the link's pose and their signed gap to the
   object's triangle mesh is computed: a KD-tree of object surface samples
   bounds it, exact closest points on the candidate triangles give it.
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
corner there (a box edge pressed into a pad). Contact points lie on the
object. Everything downstream (G, epsilon, forces) takes these contacts
unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cache, cached_property
from pathlib import Path

import numpy as np
import trimesh
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from planner.geometry.frames import tangent_bases
from planner.record.contacts import HandContacts
from planner.specs.hands import HandSpec
from planner.specs.urdf import load_model

#: [m] a link sample farther than this from every object sample is out of
#: reach (ObjectSurface.bound's default search radius).
BOUND = 0.02
#: [m] the first, short search radius of a link's samples to the object's
#: (ObjectSurface.bound): links in contact need no more (speed only).
NEAR_SEARCH = 0.006
#: [m] side of the cells that group a link's samples to bound them together
#: (speed only: any side gives the same samples).
CELL = 0.002
#: [m] round-off allowance of the cells' triangle-inequality bounds.
SLACK = 1e-9
#: Vertices with at most this many faces have their sharpness computed all
#: at once (speed only: the others one by one, the same result).
FEW_FACES = 12


@dataclass(frozen=True)
class PatchSettings:
    """Lengths in metres, angles in radians."""

    spacing: float = 0.001  # link surface sample spacing (palm: ``palm_spacing``)
    palm_spacing: float = 0.002  # the hand's root link is large and flat: coarser samples
    depth: float = 0.001  # patch = samples within (the link's smallest gap + depth) of the object
    touch: float = 0.00025  # a region whose smallest gap exceeds its link's by more does not touch
    prefilter: float = 0.003  # slack of the sampled-surface distance bound before exact queries
    max_exact: int = 600  # at most this many samples per link get exact gaps (seeded subsample)
    link_radius: float = 0.0025  # samples closer than this are neighbours (> spacing: random samples leave gaps)
    split_angle: float = float(np.radians(30.0))  # neighbours whose normals differ more are separate regions
    small: float = 0.004  # a region narrower than this stays one soft-finger contact
    max_points: int = 4  # extreme points per larger region
    sharp_angle: float = float(np.radians(25.0))  # object edges with faces farther apart are sharp
    object_spacing: float = 0.0007  # object surface samples that find the candidate triangles
    max_object_samples: int = 400_000  # a large object gets sparser samples
    seed: int = 0


@dataclass(frozen=True)
class LinkSurface:
    """Samples of one link's collision surface, link frame.

    points : (k, 3) [m]; normals : (k, 3) outward unit normals; area : (k,)
    [m^2] the surface each sample stands for.
    """

    points: np.ndarray
    normals: np.ndarray
    area: np.ndarray

    @cached_property
    def cells(self) -> Cells:
        """The samples grouped by cubes of side ``CELL``."""
        return Cells.of(self.points, np.floor(self.points / CELL).astype(np.int64))


@dataclass(frozen=True)
class Cells:
    """A grouping of link samples, link frame.

    cell : (k,) the cell of each sample; centres : (c, 3) [m] the cells'
    centroids; radius : (c,) [m] the largest distance of a cell's sample to
    its centroid.
    """

    cell: np.ndarray
    centres: np.ndarray
    radius: np.ndarray

    @classmethod
    def of(cls, points: np.ndarray, keys: np.ndarray) -> Cells:
        """``points`` (k, 3) grouped by equal rows of ``keys`` (k, 3)."""
        _, cell = np.unique(keys, axis=0, return_inverse=True)
        cell = cell.reshape(-1)
        count = np.bincount(cell)
        centres = np.stack([np.bincount(cell, points[:, i]) for i in range(3)], axis=1) / count[:, None]
        radius = np.zeros(len(count))
        np.maximum.at(radius, cell, np.linalg.norm(points - centres[cell], axis=1))
        return cls(cell, centres, radius)

    def reach(self, chosen: np.ndarray, pose: np.ndarray, obj: ObjectSurface,
              within: float) -> tuple[np.ndarray, np.ndarray]:
        """(lower (n,), upper (n,)) [m] bounds of the ``chosen`` cells' samples'
        bounds at ``pose``, by the triangle inequality about each centroid
        (inf for cells whose centroid has no object sample within ``within``)."""
        radius = self.radius[chosen]
        reach = obj.bound(self.centres[chosen] @ pose[:3, :3].T + pose[:3, 3], within)
        return reach - radius - SLACK, reach + radius + SLACK

    def members(self, chosen: np.ndarray, among: np.ndarray) -> np.ndarray:
        """(n,) ascending indices of the samples in ``among`` (k,) bool that
        lie in the ``chosen`` cells."""
        mask = np.zeros(len(self.centres), bool)
        mask[chosen] = True
        return np.flatnonzero(among & mask[self.cell])


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


# -- the hand side ----------------------------------------------------------------

def collision_mesh(model: object, link: str) -> trimesh.Trimesh | None:
    """The link's collision geometry in its link frame, as PyBullet collides it."""
    parts = []
    for c in model.link_map[link].collisions:  # type: ignore[attr-defined]
        g = c.geometry
        if g.box is not None:
            mesh = trimesh.creation.box(g.box.size)
        elif g.cylinder is not None:
            mesh = trimesh.creation.cylinder(g.cylinder.radius, g.cylinder.length, sections=64)
        elif g.sphere is not None:
            mesh = trimesh.creation.icosphere(4, g.sphere.radius)
        elif g.mesh is not None:
            mesh = trimesh.load(g.mesh.filename, force="mesh")
            if g.mesh.scale is not None:
                mesh.apply_scale(g.mesh.scale)
            mesh = mesh.convex_hull
        else:
            continue
        if c.origin is not None:
            mesh.apply_transform(c.origin)
        parts.append(mesh)
    return trimesh.util.concatenate(parts) if parts else None


def sample_surface(mesh: trimesh.Trimesh, spacing: float, rng: np.random.Generator) -> LinkSurface:
    """Area-weighted samples, about one per ``spacing``^2, with face normals."""
    count = max(int(np.ceil(mesh.area / spacing**2)), 1)
    faces = rng.choice(len(mesh.faces), size=count, p=mesh.area_faces / mesh.area)
    uv = rng.random((count, 2))
    flip = uv.sum(axis=1) > 1
    uv[flip] = 1 - uv[flip]
    tri = mesh.triangles[faces]
    points = tri[:, 0] + uv[:, :1] * (tri[:, 1] - tri[:, 0]) + uv[:, 1:] * (tri[:, 2] - tri[:, 0])
    return LinkSurface(points, mesh.face_normals[faces], np.full(count, mesh.area / count))


def hand_surfaces(hand: HandSpec, settings: PatchSettings) -> dict[str, LinkSurface]:
    """Every contact link's surface samples (once per hand and settings)."""
    return _surfaces(str(hand.urdf), hand.contact_links, hand.root_link, settings)


@cache
def _surfaces(urdf: str, links: tuple[str, ...], root: str, settings: PatchSettings) -> dict[str, LinkSurface]:
    model = load_model(Path(urdf))
    rng = np.random.default_rng(settings.seed)
    out = {}
    for link in links:
        mesh = collision_mesh(model, link)
        if mesh is not None:
            out[link] = sample_surface(mesh, settings.palm_spacing if link == root else settings.spacing, rng)
    return out


# -- the object side --------------------------------------------------------------

@dataclass
class ObjectSurface:
    """The object's triangle mesh and what exact closest points need."""

    mesh: trimesh.Trimesh
    settings: PatchSettings = field(default_factory=PatchSettings)

    @cached_property
    def _samples(self) -> tuple[cKDTree, np.ndarray]:
        """KD-tree of dense surface samples and the face of each: the candidate
        faces of exact closest points."""
        s = self.settings
        count = int(min(np.ceil(self.mesh.area / s.object_spacing**2), s.max_object_samples))
        points, faces = trimesh.sample.sample_surface(self.mesh, count, seed=s.seed)
        points = np.vstack([points, self.mesh.triangles_center])  # every face at least once
        faces = np.r_[np.asarray(faces), np.arange(len(self.mesh.faces))]
        return cKDTree(points), faces

    @cached_property
    def sharp_vertex(self) -> np.ndarray:
        """(v,) True where the faces at a vertex spread more than ``sharp_angle``."""
        m, cos = self.mesh, np.cos(self.settings.sharp_angle)
        out = np.zeros(len(m.vertices), bool)
        faces = m.vertex_faces
        normals = m.face_normals
        count = (faces >= 0).sum(axis=1)
        few = np.flatnonzero((count > 1) & (count <= FEW_FACES))
        if len(few):  # most vertices: all pairs of their faces at once (a missing face repeats the first)
            mine = faces[few, :FEW_FACES]
            mine = np.where(mine >= 0, mine, mine[:, :1])
            n = normals[mine]
            out[few] = np.einsum("vik,vjk->vij", n, n).min(axis=(1, 2)) < cos
        for v in np.flatnonzero(count > FEW_FACES):
            n = normals[faces[v][faces[v] >= 0]]
            out[v] = (n @ n.T).min() < cos
        return out

    @cached_property
    def sharp_edge(self) -> dict[tuple[int, int], bool]:
        m = self.mesh
        return {(int(min(a, b)), int(max(a, b))): bool(angle > self.settings.sharp_angle)
                for (a, b), angle in zip(m.face_adjacency_edges, m.face_adjacency_angles)}

    def bound(self, points: np.ndarray, within: float = BOUND) -> np.ndarray:
        """(k,) distance [m] of each point to the nearest surface sample (an
        upper bound of its distance to the surface, tight to ~the spacing);
        inf beyond ``within``."""
        return self._samples[0].query(points, distance_upper_bound=within)[0]

    def closest(self, points: np.ndarray, k: int = 12) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(closest (n, 3), signed gap (n,) [m], outward face normal (n, 3),
        smooth (n,) bool) of points within a few mm of the surface: exact
        closest points among the faces of the k nearest samples."""
        closest, gap, tri = self.nearest(points, k)
        normal = self.mesh.face_normals[tri]
        sign = np.where(np.einsum("ij,ij->i", points - closest, normal) < 0, -1.0, 1.0)
        return closest, sign * gap, normal, self._smooth(closest, tri)

    def nearest(self, points: np.ndarray, k: int = 12) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(closest (n, 3) [m], distance (n,) [m], face (n,)): the nearest
        point on the faces of the k nearest samples of each point."""
        tree, sample_face = self._samples
        k = min(k, tree.n)
        _, near = tree.query(points, k=k)
        cand = sample_face[np.asarray(near).reshape(len(points), k)]
        # neighbouring samples mostly share a face: each (point, face) pair once
        pairs, inverse = np.unique(np.arange(len(points))[:, None] * len(self.mesh.faces) + cand,
                                   return_inverse=True)
        row, face = np.divmod(pairs, len(self.mesh.faces))
        cp = trimesh.triangles.closest_point(self.mesh.triangles[face], points[row])
        cp = cp[inverse.reshape(-1)].reshape(len(points), k, 3)
        dist = np.linalg.norm(cp - points[:, None], axis=2)
        best = np.argmin(dist, axis=1)
        rows = np.arange(len(points))
        return cp[rows, best], dist[rows, best], cand[rows, best]

    def _smooth(self, closest: np.ndarray, tri: np.ndarray) -> np.ndarray:
        bary = trimesh.triangles.points_to_barycentric(self.mesh.triangles[tri], closest)
        on = bary >= 1e-6  # the face's vertices the point is not opposite to
        count = on.sum(axis=1)
        smooth = np.ones(len(closest), bool)
        # on a vertex: the one vertex left; on an edge: its two vertices, in order
        first = self.mesh.faces[tri, np.argmax(on, axis=1)]
        last = self.mesh.faces[tri, 2 - np.argmax(on[:, ::-1], axis=1)]
        vertex, edge = count == 1, count == 2
        smooth[vertex] = ~self.sharp_vertex[first[vertex]]
        smooth[edge] = ~self._sharp_edges(first[edge], last[edge])
        return smooth

    @cached_property
    def _edge_table(self) -> tuple[np.ndarray, np.ndarray]:
        """(sorted keys a * V + b of the mesh's shared edges, a < b; their sharpness)."""
        keys = np.array([a * len(self.mesh.vertices) + b for a, b in self.sharp_edge], np.int64)
        order = np.argsort(keys)
        return keys[order], np.array(list(self.sharp_edge.values()), bool)[order]

    def _sharp_edges(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """(n,) True where the edge (a, b) is sharp or not shared by two faces."""
        keys, sharp = self._edge_table
        if not len(keys):
            return np.ones(len(a), bool)
        want = np.minimum(a, b).astype(np.int64) * len(self.mesh.vertices) + np.maximum(a, b)
        at = np.minimum(np.searchsorted(keys, want), len(keys) - 1)
        return np.where(keys[at] == want, sharp[at], True)


# -- regions ----------------------------------------------------------------------

def link_regions(link: str, surface: LinkSurface, pose: np.ndarray, obj: ObjectSurface) -> list[Region]:
    """The contact regions of one link at ``pose`` (4, 4), link frame in the object frame."""
    s = obj.settings
    lo, hi = obj.mesh.bounds
    points = surface.points @ pose[:3, :3].T + pose[:3, 3]
    idx = np.flatnonzero(np.all((points > lo - s.prefilter) & (points < hi + s.prefilter), axis=1))
    if len(idx) == 0:
        return []
    idx = _band(surface, pose, points, idx, obj)
    if len(idx) == 0:
        return []
    weight = 1.0
    if len(idx) > s.max_exact:  # a large flat patch: a seeded subsample keeps its shape and area
        weight = len(idx) / s.max_exact
        idx = np.sort(np.random.default_rng(s.seed).choice(idx, s.max_exact, replace=False))
    closest, gap, face_normal, smooth = obj.closest(points[idx])
    floor = max(float(gap.min()), 0.0)
    keep = gap <= floor + s.depth
    idx, closest, gap, face_normal, smooth = idx[keep], closest[keep], gap[keep], face_normal[keep], smooth[keep]
    link_normal = surface.normals[idx] @ pose[:3, :3].T
    normals = np.where(smooth[:, None], -face_normal, link_normal)
    labels = _cluster(points[idx], normals, s.link_radius * np.sqrt(weight), s.split_angle)
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
          obj: ObjectSurface) -> np.ndarray:
    """The samples ``idx`` (ascending) whose bound is within depth + prefilter
    of the smallest bound of them all; none when no bound is below ``BOUND``.

    The same samples as bounding each of them (:func:`_band_reference`), but
    cells of the link's samples bound whole groups first (triangle
    inequality: a sample's bound is its cell centre's within the cell's
    radius), so only the cells near the smallest bound and those straddling
    the band's edge need their samples' own bounds.
    """
    s = obj.settings
    cells = surface.cells
    if len(idx) == 0:
        return idx
    inside = np.zeros(len(points), bool)
    inside[idx] = True
    chosen = np.flatnonzero(np.bincount(cells.cell[idx], minlength=len(cells.centres)))
    # a short search first: touching links need no more
    lower, upper = cells.reach(chosen, pose, obj, NEAR_SEARCH + cells.radius.max() + SLACK)
    if upper.min() + s.depth + s.prefilter >= NEAR_SEARCH - SLACK:  # cells out of the short search may count
        lower, upper = cells.reach(chosen, pose, obj, BOUND + cells.radius.max() + SLACK)
    if not np.isfinite(upper).any():
        return idx[:0]
    # a sample's bound is exact whatever the search radius it is found within
    near = cells.members(chosen[lower <= upper.min()], inside)  # the smallest bound lies in these cells
    bound = obj.bound(points[near], min(upper.min(), BOUND))
    if not np.isfinite(bound).any():
        return idx[:0]
    limit = bound.min() + s.depth + s.prefilter
    whole = (upper <= limit) & (upper < BOUND)  # every sample of the cell is in the band
    edge = cells.members(chosen[(lower <= limit) & ~whole], inside)
    return np.union1d(cells.members(chosen[whole], inside),
                      edge[obj.bound(points[edge], min(limit + SLACK, BOUND)) <= limit])


def _band_reference(points: np.ndarray, idx: np.ndarray, obj: ObjectSurface) -> np.ndarray:
    """:func:`_band` the plain way: every sample's bound."""
    s = obj.settings
    bound = obj.bound(points[idx], BOUND)
    if not np.isfinite(bound).any():
        return idx[:0]
    return idx[bound <= bound.min() + s.depth + s.prefilter]


def _cluster(points: np.ndarray, normals: np.ndarray, radius: float, split_angle: float) -> np.ndarray:
    """(k,) labels: connected components of samples closer than ``radius``
    whose normals differ by less than ``split_angle``."""
    pairs = cKDTree(points).query_pairs(radius, output_type="ndarray") if len(points) > 1 else np.zeros((0, 2), int)
    if len(pairs):
        pairs = pairs[np.einsum("ij,ij->i", normals[pairs[:, 0]], normals[pairs[:, 1]]) > np.cos(split_angle)]
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(points),) * 2)
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
