"""The meshes of stored objects, written into export folders (the object
of a database row is rebuilt by :func:`planner.db.objects.stored_object`).

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
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from planner import assets
from planner.db.objects import stored_object
from planner.db.store import Database, ObjectRow
from planner.errors import DatabaseError, InputError

log = logging.getLogger(__name__)

#: Folder of an export that holds the meshes, relative to the export folder.
MESH_DIR = "meshes"
#: OBJ lines: 17 significant digits give any float64 back exactly; 1-based faces.
OBJ_VERTEX, OBJ_FACE = "v %.17g %.17g %.17g", "f %d %d %d"


@dataclass(frozen=True)
class ExportedObject:
    """An object as an export folder holds it.

    ``row``: the database's row (name, mass, friction, ..., and the original
    ``source`` and ``scale``); ``file``: the mesh, relative to the export
    folder, '/'-separated; ``scale``: what turns ``file`` into metres (1: the
    file is in metres); ``label``: which success label the export writes
    (:mod:`planner.datasets.labels`); ``p_hold_outside``: where the object
    lies outside the labelled objects the exported hand's p_hold model was
    fitted on (:meth:`~planner.calibration.logistic.LogisticModel.outside`;
    empty: inside, or no model): :attr:`outside_text` is written with it.
    """

    row: ObjectRow
    file: str
    scale: float = 1.0
    label: str = "best"
    p_hold_outside: tuple[str, ...] = ()

    @property
    def outside_text(self) -> str:
        """``p_hold_outside`` as one string, '; '-separated ('' inside)."""
        return "; ".join(self.p_hold_outside)

    @property
    def name(self) -> str:
        return self.row.name


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
    exported, texts = {}, {}
    last: tuple[tuple[str, float, str], str] | None = None  # copies of one mesh are rebuilt and formatted once
    for stem, name in stems.items():
        row = _row(db, name)
        key = (row.source, row.scale, row.mesh_sha256)
        if last is None or last[0] != key or not row.mesh_sha256:
            last = key, obj_text(stored_object(row).mesh)
        relative = f"{MESH_DIR}/{stem}.obj"
        for target in (relative, *(c.format(stem=stem) for c in copies)):
            texts[out_dir / target] = (last[1].encode("utf-8"), name)
        exported[name] = ExportedObject(row, relative)
    for path, (data, name) in texts.items():  # nothing written where a file of another mesh would be replaced
        if path.is_file() and path.read_bytes() != data:
            raise InputError(f"{path} holds another mesh than this database's '{name}' (an object of "
                             "that name exported there from another database?): its grasp files would point at the "
                             "wrong mesh; export into another --out")
    for path, (data, _) in texts.items():
        path.parent.mkdir(parents=True, exist_ok=True)
        assets.atomic_write(path, data)
    log.info("wrote %d meshes to %s", len(exported), out_dir / MESH_DIR)
    return exported


def _row(db: Database, name: str) -> ObjectRow:
    row = db.object_row(name)
    if row is None:
        raise DatabaseError(f"{db.path}: object '{name}' has grasps but no row in the objects table")
    return row
