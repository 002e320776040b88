"""The two surfaces a contact patch lies between (steps 1 and 2 of :mod:`planner.plan.patches`), and the
patches' settings.

The hand side: each contact link's collision surface, sampled once per hand in its link frame
(:class:`LinkSurface`, meshes replaced by their convex hull as PyBullet collides them), its samples grouped in
cells that bound them together (:class:`Cells`). The object side: the object's triangle mesh with an AABB tree
that gives a point's exact distance and closest point (:mod:`planner.geometry.distance`), and which edges and
vertices are sharp (:class:`ObjectSurface`).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from functools import cache, cached_property
from pathlib import Path

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from planner.geometry.barycentric import barycentric
from planner.geometry.cones import nearest_in_cone, nearest_in_wedge
from planner.geometry.distance import DistanceBounds, MeshDistance
from planner.geometry.normals import ScaleNormals
from planner.specs.hands import HandSpec
from planner.specs.urdf import load_model

#: [m] a link sample farther than this from the object is out of reach (ObjectSurface.distance's default radius).
BOUND = 0.02
#: [m] side of the cells that group a link's samples to bound them together (speed only: the same samples).
CELL = 0.002
#: [m] round-off allowance of the cells' triangle-inequality bounds.
SLACK = 1e-9
#: [m] how far beyond the object's bounding box the grid of distance bounds reaches (the cells a band looks at lie
#: within BOX_MARGIN of the box, their centroids within a cell's radius more; speed only: points beyond get looser
#: bounds from the border's nodes).
GRID_MARGIN = 0.006
#: Largest number of nodes of an object's grid of distance bounds (8 bytes each; wider on a large object; speed only).
GRID_NODES = 2**21
#: [m] spacing of the grid's nodes (speed only).
GRID_SPACING = 0.002
#: Grids of distance bounds a process keeps, by mesh (the most recently used).
KEPT_GRIDS = 4
_GRIDS: dict[str, DistanceBounds] = {}
#: Vertices with at most this many faces have their sharpness computed all at once (speed only: the same result).
FEW_FACES = 12


@dataclass(frozen=True)
class PatchSettings:
    """Lengths in metres, angles in radians."""

    spacing: float = 0.001  # link surface sample spacing (palm: ``palm_spacing``)
    palm_spacing: float = 0.002  # the hand's root link is large and flat: coarser samples
    depth: float = 0.001  # patch = samples within (the link's smallest gap + depth) of the object
    touch: float = 0.00025  # a region whose smallest gap exceeds its link's by more does not touch
    # the band's slack beyond depth: closing lets penetrations up to MAX_PENETRATION (<= depth) through, and
    # PyBullet's margins a little more
    prefilter: float = 0.0003
    max_exact: int = 600  # at most this many samples per link get exact gaps (seeded subsample)
    link_radius: float = 0.0025  # samples closer than this are neighbours (> spacing: random samples leave gaps)
    split_angle: float = float(np.radians(30.0))  # neighbours whose normals differ more are separate regions
    small: float = 0.004  # a region narrower than this stays one soft-finger contact
    max_points: int = 4  # extreme points per larger region
    sharp_angle: float = float(np.radians(25.0))  # object edges with faces farther apart are sharp
    # a contact read on a collision proxy takes the exact surface's normal averaged over this radius
    # (planner.geometry.normals: a scan's triangles and its proxy's facets carry its noise)
    normal_radius: float = 0.002
    seed: int = 0


@dataclass(frozen=True)
class LinkSurface:
    """Samples of one link's collision surface, link frame.

    points : (k, 3) [m]; normals : (k, 3) outward unit normals; area : (k,) [m^2] the surface each sample stands for.
    """

    points: np.ndarray
    normals: np.ndarray
    area: np.ndarray
    _near: dict[float, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict, compare=False, repr=False,
                                                              hash=False)

    def pairs_among(self, idx: np.ndarray, radius: float) -> np.ndarray:
        """(p, 2) positions in ``idx`` (ascending sample indices) of the pairs of those samples at most ``radius``
        [m] apart, first < second: the pairs of the whole surface, found once per radius in the link frame (a pose
        moves no distance), kept where both ends are in ``idx``."""
        if radius not in self._near:
            pairs = cKDTree(self.points).query_pairs(radius, output_type="ndarray")
            pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
            self._near[radius] = (np.searchsorted(pairs[:, 0], np.arange(len(self.points) + 1)), pairs[:, 1])
        start, partner = self._near[radius]
        first, count = start[idx], start[idx + 1] - start[idx]
        at = np.repeat(first - np.cumsum(count) + count, count)  # each sample's partners: its run of the link's list
        at += np.arange(len(at))
        position = np.full(len(self.points), -1)
        position[idx] = np.arange(len(idx))
        cols = position[partner[at]]
        keep = cols >= 0
        out = np.empty((int(np.count_nonzero(keep)), 2), np.int64)
        out[:, 0], out[:, 1] = np.repeat(np.arange(len(idx)), count)[keep], cols[keep]
        return out

    @cached_property
    def cells(self) -> Cells:
        """The samples grouped by cubes of side ``CELL``."""
        return Cells.of(self.points, np.floor(self.points / CELL).astype(np.int64))


@dataclass(frozen=True)
class Cells:
    """A grouping of link samples, link frame.

    cell : (k,) the cell of each sample; centres : (c, 3) [m] the cells' centroids; radius : (c,) [m] the largest
    distance of a cell's sample to its centroid.
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

    def reach(self, chosen: np.ndarray, pose: np.ndarray, obj: ObjectSurface) -> tuple[np.ndarray, np.ndarray]:
        """(lower (n,), upper (n,)) [m] bounds of the ``chosen`` cells' samples' distances to the object at ``pose``:
        the bounds of each centroid's (:meth:`ObjectSurface.bounds`) widened by the cell's radius (triangle
        inequality); both inf for cells whose samples are all farther than ``BOUND``."""
        return self.widen(chosen, *obj.bounds(self.placed(chosen, pose)))

    def placed(self, chosen: np.ndarray, pose: np.ndarray) -> np.ndarray:
        """(n, 3) [m] the ``chosen`` cells' centroids at ``pose`` (4, 4), object frame."""
        return self.centres[chosen] @ pose[:3, :3].T + pose[:3, 3]

    def widen(self, chosen: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`reach` from the bounds ``lower``, ``upper`` (n,) [m] of the centroids' distances."""
        radius = self.radius[chosen]
        lower, upper = lower - radius - SLACK, upper + radius + SLACK
        far = lower > BOUND
        return np.where(far, np.inf, lower), np.where(far, np.inf, upper)

    def members(self, chosen: np.ndarray, among: np.ndarray) -> np.ndarray:
        """(n,) ascending indices of the samples in ``among`` (k,) bool that lie in the ``chosen`` cells."""
        mask = np.zeros(len(self.centres), bool)
        mask[chosen] = True
        return np.flatnonzero(among & mask[self.cell])


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

@dataclass(frozen=True)
class Feature:
    """Where n closest points lie on their faces: ``count`` (n,) 3 inside the face, 2 on an edge, 1 on a vertex;
    ``first``, ``last`` (n,) the feature's first and last vertex (on a vertex: the one vertex). A row depends on
    its own point and face alone: ``take(rows)`` (indices or a mask) is those rows' features, as found anew."""

    count: np.ndarray
    first: np.ndarray
    last: np.ndarray

    def take(self, rows: np.ndarray) -> Feature:
        return Feature(self.count[rows], self.first[rows], self.last[rows])


@dataclass
class ObjectSurface:
    """The object's triangle mesh, its exact closest points and its sharp edges and vertices."""

    mesh: trimesh.Trimesh
    settings: PatchSettings = field(default_factory=PatchSettings)

    @cached_property
    def _distance(self) -> MeshDistance:
        """The mesh's AABB tree: exact closest points."""
        return MeshDistance(self.mesh.vertices, self.mesh.faces)

    @cached_property
    def scale_normals(self) -> ScaleNormals:
        """The mesh's normals at a contact's scale (``settings.normal_radius``)."""
        return ScaleNormals(self.mesh)

    @cached_property
    def _bounds(self) -> DistanceBounds:
        """Bounds of distances near the object, from a grid of exact ones, shared by every ObjectSurface of the
        same mesh in this process (a sweep's units of one object fill one grid)."""
        m = self.mesh
        key = hashlib.sha256(np.ascontiguousarray(m.vertices, float).tobytes()
                             + np.ascontiguousarray(m.faces, np.int64).tobytes()).hexdigest()
        grid = _GRIDS.pop(key, None)
        if grid is None:
            lo, hi = m.bounds
            grid = DistanceBounds.around(self._distance, lo - GRID_MARGIN, hi + GRID_MARGIN, GRID_SPACING, GRID_NODES)
        _GRIDS[key] = grid  # the most recently used last
        while len(_GRIDS) > KEPT_GRIDS:
            _GRIDS.pop(next(iter(_GRIDS)))
        return grid

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

    def distance(self, points: np.ndarray, within: float = BOUND) -> np.ndarray:
        """(k,) distance [m] of each point to the surface; inf beyond ``within``."""
        dist = self._distance.nearest(points).distance
        return np.where(dist <= within, dist, np.inf)

    def bounds(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(lower (k,), upper (k,)) [m] bounds of each point's distance to the surface, no tree search
        (:class:`DistanceBounds`)."""
        return self._bounds.bounds(points)

    def closest(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(closest (n, 3), signed gap (n,) [m], outward face normal (n, 3), smooth (n,) bool): each point's closest
        point on the surface, its gap (negative inside: the side the closest face's normal says), the face's normal
        and whether the surface is smooth there."""
        return self.signed(points, *self.nearest(points))

    def signed(self, points: np.ndarray, closest: np.ndarray, distance: np.ndarray,
               face: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`closest` of ``points`` (n, 3) from their :meth:`nearest`."""
        return self.signed_features(points, closest, distance, face)[:4]  # type: ignore[return-value]

    def signed_features(self, points: np.ndarray, closest: np.ndarray, distance: np.ndarray, face: np.ndarray
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, Feature]:
        """:meth:`signed` and the closest points' :class:`Feature` (for :meth:`contact_normals`)."""
        feature, smooth = self.features(closest, face)
        return closest, self.gaps(points, closest, distance, face), self.mesh.face_normals[face], smooth, feature

    def gaps(self, points: np.ndarray, closest: np.ndarray, distance: np.ndarray, face: np.ndarray) -> np.ndarray:
        """(n,) :meth:`signed`'s gaps [m] alone (each row from its own point, closest point, distance and face)."""
        sign = np.where(np.einsum("ij,ij->i", points - closest, self.mesh.face_normals[face]) < 0, -1.0, 1.0)
        return sign * distance

    def features(self, closest: np.ndarray, face: np.ndarray) -> tuple[Feature, np.ndarray]:
        """(:class:`Feature`, smooth (n,) bool) of :meth:`signed_features` alone, row by row."""
        feature = self._feature(closest, face)
        return feature, self._smooth(feature)

    def nearest(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(closest (n, 3) [m], distance (n,) [m], face (n,)): the exact closest point of each point on the mesh."""
        found = self._distance.nearest(points)
        return found.points, found.distance, found.face

    def contact_normals(self, closest: np.ndarray, face: np.ndarray, smooth: np.ndarray,
                        toward: np.ndarray, feature: Feature | None = None) -> np.ndarray:
        """(n, 3) unit contact normals into the object at ``closest`` (n, 3) on faces ``face``: the face's where the
        surface is smooth there (``smooth``, from :meth:`signed`); at a sharp edge or vertex, the direction of its
        normal cone (the outward normals of the faces that meet there, and their non-negative combinations) nearest
        the other body's ``toward`` (n, 3), its own normal into the object: a pad laid on an edge keeps its normal,
        a link's side or rim touching an edge gets the nearest normal the object can have there (the side's normal
        pushed the object out through a face no finger touched). Where the edge or vertex has no cone (an open
        border), ``toward``. ``feature``: the points' :class:`Feature`, if known. Row by row."""
        normals = np.where(smooth[:, None], -self.mesh.face_normals[face], toward)
        sharp = np.flatnonzero(~smooth)
        if not len(sharp):
            return normals
        found = self._feature(closest[sharp], face[sharp]) if feature is None else feature.take(sharp)
        count, first, last = found.count, found.first, found.last
        edge = count == 2
        if edge.any():
            at, known = self._edge_faces(first[edge], last[edge])
            rows = sharp[edge][known]
            n = self.mesh.face_normals[at[known]]
            wedge = -nearest_in_wedge(n[:, 0], n[:, 1], -toward[rows])
            normals[rows] = np.where(np.isfinite(wedge), wedge, toward[rows])
        for row, vertex in zip(sharp[count == 1], first[count == 1]):
            faces = self.mesh.vertex_faces[vertex]
            cone = -nearest_in_cone(self.mesh.face_normals[faces[faces >= 0]], -toward[row])
            normals[row] = cone if np.isfinite(cone).all() else toward[row]
        return normals

    def _feature(self, closest: np.ndarray, tri: np.ndarray) -> Feature:
        """The :class:`Feature` of points ``closest`` (n, 3) on faces ``tri`` (n,)."""
        on = barycentric(self.mesh.triangles[tri], closest) >= 1e-6  # the vertices the point is not opposite to
        first = self.mesh.faces[tri, np.argmax(on, axis=1)]
        last = self.mesh.faces[tri, 2 - np.argmax(on[:, ::-1], axis=1)]
        return Feature(on.sum(axis=1), first, last)

    def _smooth(self, feature: Feature) -> np.ndarray:
        count, first, last = feature.count, feature.first, feature.last
        smooth = np.ones(len(count), bool)
        vertex, edge = count == 1, count == 2
        smooth[vertex] = ~self.sharp_vertex[first[vertex]]
        smooth[edge] = ~self._sharp_edges(first[edge], last[edge])
        return smooth

    @cached_property
    def _edge_table(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(sorted keys a * V + b of the mesh's shared edges, a < b; their
        sharpness; (e, 2) the two faces that share each)."""
        m = self.mesh
        edges = np.sort(np.asarray(m.face_adjacency_edges, np.int64).reshape(-1, 2), axis=1)
        keys = edges[:, 0] * len(m.vertices) + edges[:, 1]
        order = np.argsort(keys, kind="stable")
        sharp = np.asarray(m.face_adjacency_angles, float).reshape(-1) > self.settings.sharp_angle
        return keys[order], sharp[order], np.asarray(m.face_adjacency, np.int64).reshape(-1, 2)[order]

    def _lookup(self, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(index into :attr:`_edge_table` of each edge (a, b), whether the edge is there)."""
        keys = self._edge_table[0]
        if not len(keys):
            return np.zeros(len(a), np.int64), np.zeros(len(a), bool)
        want = np.minimum(a, b).astype(np.int64) * len(self.mesh.vertices) + np.maximum(a, b)
        # the last of equal keys (none: trimesh's face_adjacency leaves out an edge of more than two faces,
        # which falls back to the link's normal as an open border does)
        at = np.maximum(np.searchsorted(keys, want, side="right") - 1, 0)
        return at, keys[at] == want

    def _sharp_edges(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """(n,) True where the edge (a, b) is sharp or not shared by two faces."""
        at, known = self._lookup(a, b)
        sharp = self._edge_table[1]
        return np.where(known, sharp[at], True) if len(sharp) else np.ones(len(a), bool)

    def _edge_faces(self, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """((n, 2) the faces that share each edge (a, b), whether it has two)."""
        at, known = self._lookup(a, b)
        faces = self._edge_table[2]
        return (faces[at] if len(faces) else np.zeros((len(a), 2), np.int64)), known

