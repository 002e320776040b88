"""Loading and checking object meshes: the only place that repairs geometry.

All lengths are metres. A mesh that cannot be made into a closed, finite,
non-flat solid of plausible size is refused with a :class:`MeshError` that
says what to fix.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import trimesh

from planner import prepare
from planner.errors import MeshError
from planner.geometry.gltf import gltf_problem
from planner.specs.objects import MESH_SUFFIXES

log = logging.getLogger(__name__)

#: Files larger than this are refused before parsing (bounded memory).
MAX_FILE_BYTES = 256 * 1024 * 1024
#: Meshes with more faces are refused: ask the user to simplify them first.
MAX_FACES = 1_000_000
#: Largest extent [m] of an object any built-in hand could conceivably hold.
MAX_EXTENT = 1.5
#: Smallest extent [m]: below a millimetre the mesh is almost surely in the
#: wrong units (or not an object at all).
MIN_EXTENT = 1e-3
#: Volume [m^3] under which a closed mesh counts as flat (a 1 mm^3 solid).
MIN_VOLUME = 1e-9
#: Said where a URDF is read as a mesh file (:func:`planner.geometry.solid.load_object` reads it as an object).
URDF_HINT = " (a URDF describes an object, not a mesh: give it as the object, e.g. grasp generate obj.urdf)"


def load_mesh_file(path: Path, scale: float = 1.0) -> trimesh.Trimesh:
    """Read a mesh file into one triangle mesh, scaled to metres, and check it."""
    return checked_solid(read_mesh_file(path, scale), str(path))


def read_mesh_file(path: Path, scale: float | np.ndarray = 1.0) -> trimesh.Trimesh:
    """A mesh file's triangles as they are, scaled (``scale``: one factor, or (3,) one per axis), unchecked:
    :func:`checked_solid` makes a solid of them."""
    if not path.exists():
        raise MeshError(f"{path}: file not found")
    if path.suffix.lower() not in MESH_SUFFIXES:
        raise MeshError(f"{path}: unsupported mesh type '{path.suffix}'; use one of {', '.join(MESH_SUFFIXES)}"
                        f"{URDF_HINT if path.suffix.lower() == '.urdf' else ''}")
    size = path.stat().st_size
    if size == 0:
        raise MeshError(f"{path}: file is empty")
    if size > MAX_FILE_BYTES:
        raise MeshError(f"{path}: {size / 2**20:.0f} MiB is too large; simplify the mesh below {MAX_FACES:,} faces")
    if not np.all(np.isfinite(scale)) or np.any(np.asarray(scale) <= 0):
        raise MeshError(f"{path}: scale must be a positive number, got {scale}")
    unreadable = gltf_problem(path)  # a .gltf without its buffers, compressed geometry trimesh cannot decode here
    if unreadable:
        raise MeshError(f"{path}: cannot read it: {unreadable}")
    try:
        loaded = trimesh.load(str(path), force="mesh", process=False)
    except Exception as exc:  # trimesh raises many types for broken files
        # a KeyError's text alone ("cannot parse mesh: 'y'": a PLY without a y property) says nothing
        reason = f"{exc.args[0]!r} is missing" if isinstance(exc, KeyError) and exc.args else str(exc)
        raise MeshError(f"{path}: cannot parse mesh: {reason} (re-export it as OBJ/STL/PLY/GLB)") from exc
    if not isinstance(loaded, trimesh.Trimesh):
        raise MeshError(f"{path}: holds no triangles")
    if len(loaded.faces) == 0:
        _refuse_point_cloud(path)
        raise MeshError(f"{path}: mesh has no triangles")
    return trimesh.Trimesh(np.asarray(loaded.vertices, float) * scale, np.asarray(loaded.faces), process=False)


def _refuse_point_cloud(path: Path) -> None:
    """A MeshError where ``path`` holds points alone (a scanner's PLY), which ``force="mesh"`` reads as no mesh."""
    try:
        points = trimesh.load(str(path), process=False)
    except Exception:  # read once already: the caller says what is missing
        return
    clouds = list(points.geometry.values()) if isinstance(points, trimesh.Scene) else [points]  # a .glb's: a scene
    count = sum(len(c.vertices) for c in clouds if isinstance(c, trimesh.PointCloud))
    if count and not any(isinstance(c, trimesh.Trimesh) and len(c.faces) for c in clouds):
        raise MeshError(f"{path}: a point cloud of {count:,} points, no triangles: make a surface of it first (a "
                        "Poisson reconstruction: MeshLab, Open3D)")


def checked_solid(mesh: trimesh.Trimesh, where: str) -> trimesh.Trimesh:
    """Validate and repair ``mesh`` into a closed solid, or raise MeshError."""
    if len(mesh.faces) == 0 or len(mesh.vertices) == 0:
        raise MeshError(f"{where}: mesh has no triangles")
    if len(mesh.faces) > MAX_FACES:
        raise MeshError(f"{where}: {len(mesh.faces):,} faces; simplify it below {MAX_FACES:,} first")
    if not np.all(np.isfinite(mesh.vertices)):
        raise MeshError(f"{where}: mesh has NaN or infinite vertex coordinates")
    given = mesh
    mesh = _cleaned(mesh)
    if len(mesh.faces) == 0:
        raise MeshError(f"{where}: every triangle is degenerate (zero area)")
    check_extent(mesh, where)
    repaired = ""
    if not mesh.is_watertight:
        with np.errstate(divide="ignore", invalid="ignore"):  # a flat piece's centre of mass is 0/0: refused
            mesh, repaired = _repair(mesh, where, given)
    with np.errstate(divide="ignore", invalid="ignore"):  # a flat mesh's centre of mass is 0/0: refused below
        trimesh.repair.fix_normals(mesh, multibody=True)
        volume = float(mesh.volume)
    if volume < 0:
        mesh.invert()
    if abs(volume) < MIN_VOLUME:
        raise MeshError(f"{where}: mesh encloses no volume ({abs(volume):.3g} m^3): it is flat or open")
    bodies = _bodies(mesh)
    flat = _flat_bodies(bodies)
    if flat:  # a sheet closed into nothing by the repair: no mass, yet it would set the torque scale and collide
        raise MeshError(f"{where}: {flat}; remove it in a mesh editor")
    if repaired:  # said once the mesh is taken: a refused one gets its one line alone
        prepare.noted(where, f"{repaired} (once: cached afterwards)")
    gap = _origin_gap(mesh)
    if gap > max(FAR_ORIGIN, float(np.max(mesh.extents))):
        prepare.noted(where, f"its frame's origin lies {gap:.2g} m from the mesh (a part exported in an assembly's "
                             "frame?): its grasps, exports and --object-pose are in that frame; move the mesh to the "
                             "origin in a mesh editor if that is not meant (once: cached afterwards)")
    apart = _apart(bodies)
    if apart:
        prepare.noted(where, f"{apart} of its {len(bodies)} bodies stand apart from the others (their boxes meet no "
                             "other's): the whole is taken as one rigid object (a grasp of one part lifts all); "
                             "split the file to plan each on its own (once: cached afterwards)")
    return mesh


#: [m] the least distance of a mesh from its frame's origin that is said (and more than the mesh's size):
#: a CAD part exported in its assembly's frame, whose grasp poses and --object-pose are in that frame.
FAR_ORIGIN = 0.1


def _origin_gap(mesh: trimesh.Trimesh) -> float:
    """[m] the distance from the frame's origin to ``mesh``'s bounding box (0 inside it)."""
    lo, hi = mesh.bounds
    return float(np.linalg.norm(np.maximum(lo, 0.0) + np.maximum(-hi, 0.0)))


def _bodies(mesh: trimesh.Trimesh) -> list[trimesh.Trimesh]:
    """``mesh``'s bodies as its faces join them when there are several; [] for one."""
    return list(mesh.split(only_watertight=False, repair=False)) if mesh.body_count > 1 else []


def _apart(bodies: list[trimesh.Trimesh]) -> int:
    """How many of ``bodies`` have a box, widened by :data:`BODY_MARGIN`, that meets no other's (0: they touch,
    as convex pieces and CAD parts do)."""
    if len(bodies) < 2:
        return 0
    lo = np.array([b.bounds[0] for b in bodies]) - BODY_MARGIN
    hi = np.array([b.bounds[1] for b in bodies]) + BODY_MARGIN
    meets = np.all((lo[:, None] <= hi[None]) & (lo[None] <= hi[:, None]), axis=2)
    return int((meets.sum(axis=1) == 1).sum())


#: Share of the bodies' summed volume their union may lack and still count as
#: their sum: bodies that touch (the built-ins' convex pieces) keep their own
#: mass properties to the last bit; bodies that overlap take their union's.
OVERLAP_TOL = 1e-6


def union_of_bodies(mesh: trimesh.Trimesh, where: str) -> trimesh.Trimesh | None:
    """The union of ``mesh``'s bodies when they overlap, whose volume, centre
    of mass and inertia are the object's (summed, the bodies count the
    shared volume twice); None when they do not (one body, no two bodies'
    boxes meet, or the union lacks less than :data:`OVERLAP_TOL` of their
    sum). The boolean is manifold3d's, through trimesh; where it fails on
    these bodies the bodies' sum stands, with a warning (the same every time:
    it is cached so); without manifold3d, a MeshError."""
    bodies = mesh.split(only_watertight=False)
    if len(bodies) < 2:
        return None
    lo, hi = np.array([b.bounds[0] for b in bodies]), np.array([b.bounds[1] for b in bodies])
    # any two boxes meet? one body against the later ones at a time: memory grows with the bodies, not their square
    if not any(np.all((lo[i] < hi[i + 1:]) & (lo[i + 1:] < hi[i]), axis=1).any() for i in range(len(bodies) - 1)):
        return None
    try:
        import manifold3d  # noqa: F401 - trimesh's boolean engine
    except ImportError:
        raise MeshError(f"{where}: its bodies overlap, and their union needs manifold3d, a dependency of this "
                        "planner: pip install -e .") from None
    try:
        union = trimesh.boolean.union(bodies, engine="manifold")
    except Exception as exc:  # manifold3d refuses a body it cannot read as a solid
        log.warning("%s: the union of its %d bodies failed (%s): their summed volume stands", where, len(bodies), exc)
        return None
    total = float(sum(b.volume for b in bodies))
    if not (isinstance(union, trimesh.Trimesh) and 0 < union.volume <= total * (1 + OVERLAP_TOL)):
        log.warning("%s: the union of its %d bodies is not a solid within theirs: their summed volume stands",
                    where, len(bodies))
        return None
    return union if union.volume < total * (1 - OVERLAP_TOL) else None


#: Units a mesh file too large in metres may be in, and the --scale each takes (US CAD exports inches).
UNITS = (("millimetres", 0.001), ("centimetres", 0.01), ("inches", 0.0254))


def check_extent(mesh: trimesh.Trimesh, where: str) -> None:
    extent = float(np.max(mesh.extents))
    if extent > MAX_EXTENT:
        units = ", ".join(f"in {unit}{' pass' if i == 0 else ''} --scale {factor:g} ({extent * factor:.2g} m across)"
                          for i, (unit, factor) in enumerate(UNITS))
        raise MeshError(f"{where}: object is {extent:.3g} m across, larger than any hand can grasp; if the mesh is "
                        f"{units}")
    if extent < MIN_EXTENT:
        raise MeshError(
            f"{where}: object is {extent * 1000:.3g} mm across, smaller than a millimetre; "
            "if the mesh is in other units pass --scale"
        )


def _cleaned(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """A copy of ``mesh`` with its vertices at one position merged (a UV seam
    closes), its zero-area triangles and repeated ones (an exporter's
    leftovers, the same three corners in any order) dropped, and its unused
    vertices."""
    mesh = mesh.copy()
    mesh.merge_vertices()
    mesh.update_faces(mesh.nondegenerate_faces())
    mesh.update_faces(mesh.unique_faces())
    mesh.remove_unreferenced_vertices()
    return mesh


def _closed(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """``mesh``, or with its small holes closed: trimesh's fill (in place),
    then a fan cap on each open loop; watertight only if that closed it."""
    trimesh.repair.fill_holes(mesh)
    return mesh if mesh.is_watertight else cap_boundary_loops(mesh)


def _repair(mesh: trimesh.Trimesh, where: str, given: trimesh.Trimesh) -> tuple[trimesh.Trimesh, str]:
    """Close small holes (:func:`_closed`); else the file's own bodies, each
    closed, kept apart (:func:`closed_bodies`). Returns the mesh and the
    geometry added to it, in words ('' when none was)."""
    capped = _closed(mesh)
    if capped is mesh and mesh.is_watertight:
        return mesh, "filled small holes in the mesh"
    if not capped.is_watertight:
        apart = closed_bodies(given)
        if apart is not None:
            return apart, ""  # no geometry added: the file's own closed bodies, read as such (V-HACD pieces)
        flat = _flat_bodies(_bodies(given))
        raise MeshError(
            f"{where}: {flat}; remove it in a mesh editor" if flat else
            f"{where}: mesh is not watertight and could not be repaired "
            "(non-manifold edges or self-overlapping holes); close it in a mesh editor"
        )
    return capped, "capped the mesh's open boundary loops, closing it into a solid"


#: A body whose vertices lie within this fraction of its size of one plane is flat.
FLAT_TOL = 1e-9
#: [m] how far boxes are widened where bodies are compared: a flat body within the box of the object's other
#: bodies is inside or on it (kept); a body whose box meets no other's stands apart (noted).
BODY_MARGIN = 1e-3


def _flat_bodies(bodies: list[trimesh.Trimesh]) -> str:
    """What is flat among an object's ``bodies`` (:func:`_bodies`; a sheet, a ground plane, a
    scrap triangle of a scan: no volume), said in words; '' when none is. A
    flat piece with a corner on another body (a fin on an edge) is not a body
    of its own: the caller's other message says what is wrong there; one
    within the other bodies' box (an internal face, a decal) is left as it was."""
    if len(bodies) < 2:
        return ""
    flat, solid = [], []
    for body in bodies:
        points = np.asarray(body.vertices) - body.vertices.mean(axis=0)
        sing = np.linalg.svd(points, compute_uv=False) if len(points) > 2 else np.zeros(3)
        (flat if len(sing) < 3 or sing[2] <= FLAT_TOL * max(sing[0], 1e-12) else solid).append(body)
    corners = {tuple(v) for body in solid for v in np.round(body.vertices, 9)}
    flat = [body for body in flat if not any(tuple(v) in corners for v in np.round(body.vertices, 9))]
    if solid:  # a face inside the object or on it (an internal face, a decal) changes neither its reach nor its mass
        lo = np.min([b.bounds[0] for b in solid], axis=0) - BODY_MARGIN
        hi = np.max([b.bounds[1] for b in solid], axis=0) + BODY_MARGIN
        flat = [body for body in flat if not (np.all(body.vertices >= lo) and np.all(body.vertices <= hi))]
    if not flat:
        return ""
    first = flat[0]
    return (f"{len(flat)} of its {len(bodies)} bodies {'is' if len(flat) == 1 else 'are'} flat, enclosing no "
            f"volume (a sheet, a ground plane or a scrap of scan; one {np.max(first.extents) * 1000:.3g} mm "
            f"across at {', '.join(f'{c:.3g}' for c in first.bounds.mean(axis=0))} m)")


def closed_bodies(given: trimesh.Trimesh) -> trimesh.Trimesh | None:
    """The bodies of ``given`` as its faces join them (its own vertex
    indices), each with its vertices merged, side by side; None unless there
    are several and each is closed. Convex pieces that touch (the V-HACD
    pieces of pybullet_data's random objects, CAD parts) share edges once
    their vertices are merged across pieces, four faces on one edge: not a
    solid. Kept apart, each piece is one; their union's mass properties
    are the object's (:func:`union_of_bodies`)."""
    pieces = given.split(only_watertight=False, repair=False)
    if len(pieces) < 2:
        return None
    closed = []
    for piece in pieces:
        piece = _cleaned(piece)
        if len(piece.faces) and not piece.is_watertight:  # a piece's small holes, closed as a whole mesh's are
            piece = _closed(piece)
        if not len(piece.faces) or not piece.is_watertight or abs(piece.volume) < MIN_VOLUME:
            return None  # open, or a flat piece (a fin) closed into nothing
        closed.append(piece)
    return trimesh.util.concatenate(closed)


def cap_boundary_loops(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """Close every open boundary loop with a fan around the loop's centroid.

    A boundary edge is a directed edge ``a -> b`` (in face winding) whose
    reverse is not in the mesh; its cap triangle ``(b, a, centre)`` keeps the
    winding consistent.
    """
    edges = mesh.edges_sorted
    single = trimesh.grouping.group_rows(edges, require_count=1)
    if len(single) == 0:
        return mesh
    directed = mesh.edges[single]
    loops = trimesh.graph.connected_components(directed, min_len=3)
    vertices = [np.asarray(mesh.vertices)]
    faces = [np.asarray(mesh.faces)]
    next_index = len(mesh.vertices)
    for loop in loops:
        members = np.isin(directed[:, 0], loop) & np.isin(directed[:, 1], loop)
        centre = mesh.vertices[np.asarray(loop)].mean(axis=0)
        vertices.append(centre[None, :])
        loop_edges = directed[members]
        faces.append(np.column_stack([loop_edges[:, 1], loop_edges[:, 0], np.full(len(loop_edges), next_index)]))
        next_index += 1
    return trimesh.Trimesh(np.vstack(vertices), np.vstack(faces), process=False)


def mesh_hash(mesh: trimesh.Trimesh) -> str:
    """Content hash of the geometry (vertices rounded to 0.1 um, and faces)."""
    import hashlib

    h = hashlib.sha256()
    h.update(np.round(np.asarray(mesh.vertices, np.float64), 7).tobytes())
    h.update(np.asarray(mesh.faces, np.int64).tobytes())
    return h.hexdigest()
