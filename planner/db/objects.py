"""The object a database row describes, rebuilt as the planner had it: one
function for every stage that reads stored objects (``grasp validate``,
exports, queries).

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
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

from planner import assets
from planner.db.store import ObjectRow
from planner.errors import InputError, PlannerError
from planner.geometry.solid import PreparedObject, prepare
from planner.specs.objects import PRIMITIVES, ObjectSpec, builtin_specs, is_registered, resolve_spec

PRIMITIVE_PREFIX = "primitive:"
PYBULLET_DATA = "pybullet_data"


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
