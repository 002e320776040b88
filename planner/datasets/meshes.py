"""The meshes of stored objects: rebuilt from the database, written into
export folders.

An ``objects`` row keeps where the object's mesh came from (``source``: a
mesh file, or ``primitive:box`` ...), the ``scale`` that turns that file into
metres, and the hash of the checked mesh the planner used
(:func:`planner.geometry.mesh.mesh_hash`). :func:`stored_object` rebuilds the
object from the first of these that gives back that hash:

1. the source file at the stored scale (a file of a ``pybullet_data``
   package that is not at the stored path, e.g. a database from another
   machine, is looked up in this machine's package);
2. the built-in object of the same name;
3. for a primitive, a built-in primitive of the same kind (a copy or a
   renamed object).

So the mesh is the one the grasps were planned on, in the object frame, or
an :class:`~planner.errors.InputError` says why it cannot be had. Mass and
friction are the stored ones.

Export folders hold one mesh per object, ``DIR/meshes/<object>.obj``
(:data:`MESH_DIR`; '/' in names becomes '__'): the checked mesh as one plain
OBJ (``v`` and ``f`` lines only: no normals, textures, groups or materials,
so ``trimesh.load`` returns a single ``Trimesh``), vertices **in metres**
(the files' ``scale`` is 1) in the planner's vertex and face order, each
coordinate to 17 significant digits, which gives every float64 back
exactly. ACRONYM's ``load_mesh(file, mesh_root_dir=DIR)`` (join, load,
``apply_scale(1)``) therefore returns the planner's vertices bit for bit,
and the mesh hash with them. (trimesh's own OBJ writer prints a fixed number
of decimals, which cannot do that for every coordinate.)
"""

from __future__ import annotations

import io
import logging
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import trimesh

from planner import assets
from planner.db.store import Database, ObjectRow
from planner.errors import DatabaseError, InputError, PlannerError
from planner.geometry.solid import PreparedObject, prepare
from planner.specs.objects import PRIMITIVES, ObjectSpec, builtin_specs, is_registered, resolve_spec

log = logging.getLogger(__name__)

#: Folder of an export that holds the meshes, relative to the export folder.
MESH_DIR = "meshes"
#: OBJ lines: 17 significant digits give any float64 back exactly; 1-based faces.
OBJ_VERTEX, OBJ_FACE = "v %.17g %.17g %.17g", "f %d %d %d"
PRIMITIVE_PREFIX = "primitive:"
PYBULLET_DATA = "pybullet_data"


@dataclass(frozen=True)
class ExportedObject:
    """An object as an export folder holds it.

    ``row``: the database's row (name, mass, friction, ..., and the original
    ``source`` and ``scale``); ``file``: the mesh, relative to the export
    folder, '/'-separated; ``scale``: what turns ``file`` into metres (1: the
    file is in metres).
    """

    row: ObjectRow
    file: str
    scale: float = 1.0

    @property
    def name(self) -> str:
        return self.row.name


def stored_object(row: ObjectRow) -> PreparedObject:
    """The object a database row describes, with the stored mass and friction,
    rebuilt as the planner had it (see the module docstring)."""
    tried: list[str] = []
    for spec in _candidates(row):
        try:
            obj = prepare(spec)
        except PlannerError as exc:
            tried.append(str(exc))
            continue
        if not row.mesh_sha256 or obj.mesh_hash == row.mesh_sha256:
            return obj
        tried.append(f"{spec.source or spec.kind} gives another mesh than the database's")
    raise InputError(f"object '{row.name}': cannot rebuild the mesh its grasps were planned on "
                     f"({'; '.join(tried) or 'no source'})")


def _candidates(row: ObjectRow) -> Iterator[ObjectSpec]:
    props = {"mass": row.mass, "friction": row.friction}
    kind = row.source[len(PRIMITIVE_PREFIX):] if row.source.startswith(PRIMITIVE_PREFIX) else None
    if kind is None:
        yield ObjectSpec(name=row.name, kind="mesh", source=str(local_file(Path(row.source))), scale=row.scale,
                         **props)
    if is_registered(row.name):
        yield replace(resolve_spec(row.name), **props)
    if kind in PRIMITIVES:
        for spec in builtin_specs().values():
            if spec.kind == kind and spec.name != row.name:
                yield replace(spec, name=row.name, **props)


def local_file(path: Path) -> Path:
    """``path``, or the same file in this machine's ``pybullet_data`` when
    ``path`` is missing and lies in some ``pybullet_data`` folder."""
    if path.is_file() or PYBULLET_DATA not in path.parts:
        return path
    parts = path.parts
    inside = parts[len(parts) - parts[::-1].index(PYBULLET_DATA):]
    moved = assets.pybullet_data_root().joinpath(*inside)
    return moved if moved.is_file() else path


def mesh_stem(name: str) -> str:
    """A file name for an object name: path separators become ``__``."""
    return name.replace("/", "__").replace("\\", "__")


def obj_text(mesh: trimesh.Trimesh) -> str:
    """One plain OBJ of ``mesh``: its vertices [m] and faces, in its order."""
    out = io.StringIO()
    np.savetxt(out, np.asarray(mesh.vertices, np.float64), fmt=OBJ_VERTEX)
    np.savetxt(out, np.asarray(mesh.faces, np.int64) + 1, fmt=OBJ_FACE)
    return out.getvalue()


def write_meshes(db: Database, names: Sequence[str], out_dir: Path, copies: Sequence[str] = ()
                 ) -> dict[str, ExportedObject]:
    """Write ``DIR/meshes/<object>.obj`` for each object (and the same bytes
    at each of ``copies``: paths relative to ``out_dir``, with ``{stem}``).
    The exporter writes the meshes before any grasp file, so an object whose
    mesh cannot be rebuilt stops the export before a grasp file is written."""
    stems: dict[str, str] = {}
    for name in names:
        stem = mesh_stem(name)
        if stem in stems:
            raise InputError(f"objects '{stems[stem]}' and '{name}' would share the mesh file {stem}.obj; "
                             "export them separately (--object)")
        stems[stem] = name
    exported = {}
    last: tuple[tuple[str, float, str], str] | None = None  # copies of one mesh are rebuilt and formatted once
    for stem, name in stems.items():
        row = _row(db, name)
        key = (row.source, row.scale, row.mesh_sha256)
        if last is None or last[0] != key or not row.mesh_sha256:
            last = key, obj_text(stored_object(row).mesh)
        text = last[1]
        relative = f"{MESH_DIR}/{stem}.obj"
        for target in (relative, *(c.format(stem=stem) for c in copies)):
            path = out_dir / target
            path.parent.mkdir(parents=True, exist_ok=True)
            assets.atomic_write(path, text.encode("utf-8"))
        exported[name] = ExportedObject(row, relative)
    log.info("wrote %d meshes to %s", len(exported), out_dir / MESH_DIR)
    return exported


def _row(db: Database, name: str) -> ObjectRow:
    row = db.object_row(name)
    if row is None:
        raise DatabaseError(f"{db.path}: object '{name}' has grasps but no row in the objects table")
    return row
