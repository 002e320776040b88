"""The object a database row describes, rebuilt as the planner had it: one
function for every stage that reads stored objects (``grasp validate``,
exports, queries).

An ``objects`` row keeps where the object's mesh came from (``source``: a
mesh file, a URDF file, or ``primitive:box`` ...), the ``scale`` that turns
that file into metres, and the hash of the checked mesh the planner used
(:func:`planner.geometry.mesh.mesh_hash`). :func:`stored_object` rebuilds the
object from the first of these that gives back that hash:

1. the source file at the stored scale (a file of a ``pybullet_data``
   package that is not at the stored path, e.g. a database from another
   machine, is looked up in this machine's package);
2. the built-in object of the same name;
3. for a primitive, a built-in primitive of the same kind (a copy or a
   renamed object).

So the mesh is the one the grasps were planned on, in the object frame, or
an :class:`~planner.errors.InputError` says why it cannot be had (a URDF file
made of its stored ``geometry``). Mass, friction, up, centre of mass and
inertia are the stored ones.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import numpy as np

from planner import assets
from planner.db.store import ObjectRow
from planner.errors import InputError, PlannerError
from planner.geometry.solid import PreparedObject, prepare
from planner.record.field import same_inertial as same_inertial_values
from planner.specs.objects import (
    PRIMITIVES,
    PROPERTY_RTOL,
    URDF_FILE,
    ObjectSpec,
    builtin_specs,
    is_registered,
    resolve_spec,
)
from planner.specs.urdf_objects import URDF_SUFFIX

PRIMITIVE_PREFIX = "primitive:"
PYBULLET_DATA = "pybullet_data"


def stored_object(row: ObjectRow) -> PreparedObject:
    """The object a database row describes, with the stored mass, friction,
    up, centre of mass and inertia, rebuilt as the planner had it (see the module docstring)."""
    tried: list[str] = []
    for spec in _candidates(row):
        try:
            obj = prepare(spec)
        except PlannerError as exc:
            tried.append(str(exc))
            continue
        if not row.mesh_sha256 or obj.mesh_hash == row.mesh_sha256:
            return obj if same_inertial(row, obj) else prepare(replace(
                obj.spec, com=tuple(float(v) for v in row.com), com_from="stored",
                gyration=tuple(float(v) for v in np.ravel(row.inertia) / row.mass)))
        tried.append(f"{spec.source or spec.kind} gives another mesh than the database's")
    raise InputError(f"object '{row.name}': cannot rebuild the mesh its grasps were planned on "
                     f"({'; '.join(tried) or 'no source'})")


#: How far a prepared object's volume (relative) may lie from its stored row's and still be the stored object's
#: (its centre of mass: COM_TOL, kept to 0.1 um).
VOLUME_RTOL = 1e-6
def same_inertial(row: ObjectRow, obj: PreparedObject) -> bool:
    """Whether ``obj``'s centre of mass and inertia are ``row``'s, to what the store keeps."""
    return same_inertial_values(obj.com, obj.inertia, row.com, row.inertia)


def differs(row: ObjectRow, obj: PreparedObject) -> str | None:
    """Why ``obj`` is not the object ``row`` stores under its name (None: it
    is): another mesh (another file of that name, the file edited since,
    another scale, a URDF's other geometry), other mass properties from the same mesh (an earlier
    planner's: overlapping bodies are counted once since 2026-12-05), another centre of mass or inertia
    (given, or no more), or another mass, friction or up. Grasps planned on one are not grasps of the
    other."""
    if row.mesh_sha256 and obj.mesh_hash != row.mesh_sha256:
        if obj.spec.kind == URDF_FILE and obj.spec.geometry != row.geometry:
            return (f"of its <{row.geometry}> elements, now of its <{obj.spec.geometry}> ({row.source}): give "
                    f"--geometry {row.geometry} (or a sidecar's or manifest line's geometry={row.geometry}) to go on "
                    "with it")
        return (f"from another mesh than {obj.source_file} at scale {obj.file_scale:.10g} gives now (stored: "
                f"{row.source} at scale {row.scale:.10g}; another file of that name, the file edited since, or another "
                "scale)")
    if not math.isclose(obj.volume, row.volume, rel_tol=VOLUME_RTOL):
        return (f"with a volume of {row.volume * 1e6:.6g} cm^3 where this planner makes the same mesh "
                f"{obj.volume * 1e6:.6g} cm^3 (an earlier planner's mass properties: overlapping bodies are counted "
                "once since 2026-12-05)")
    if not same_inertial(row, obj):
        now = ("the mesh's" if obj.spec.com is None else "as given" if obj.spec.com_from == "as given" else
               f"given by {obj.spec.com_from}")  # a flag's or a manifest line's: "given by as given" read
        return (f"with its centre of mass at {_point(row.com)} m and principal moments {_point(_moments(row.inertia))} "
                f"kg m^2 (now {_point(obj.com)}, {now}, and {_point(_moments(obj.inertia))})")
    if not (math.isclose(obj.mass, row.mass, rel_tol=PROPERTY_RTOL) and
            math.isclose(obj.friction, row.friction, rel_tol=PROPERTY_RTOL)):
        return f"with mass {row.mass:g}, friction {row.friction:g} (now {obj.mass:g}, {obj.friction:g})"
    if obj.spec.up != row.up:
        return f"with up {row.up} (now {obj.spec.up})"
    return None


def _point(values: np.ndarray) -> str:
    return "[" + ", ".join(f"{v:.4g}" for v in np.ravel(values)) + "]"


def _moments(inertia: np.ndarray) -> np.ndarray:
    return np.linalg.eigvalsh(0.5 * (np.asarray(inertia) + np.asarray(inertia).T))


def _candidates(row: ObjectRow) -> Iterator[ObjectSpec]:
    props = {"mass": row.mass, "friction": row.friction, "up": row.up}
    kind = row.source[len(PRIMITIVE_PREFIX):] if row.source.startswith(PRIMITIVE_PREFIX) else None
    if kind is None:
        source = local_file(Path(row.source))
        urdf = source.suffix.lower() == URDF_SUFFIX
        yield ObjectSpec(name=row.name, kind=URDF_FILE if urdf else "mesh", source=str(source), scale=row.scale,
                         geometry=row.geometry if urdf else "collision", **props)
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
