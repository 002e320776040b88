"""What a user's words name, checked against a database: the object ``name``
means (stored, built-in, ``random_NNN`` or a mesh file), a stored object
rebuilt, a typed pose, and the ``grasp generate`` command that plans an object;
the default database path every API function opens.
"""

from __future__ import annotations

import math
import shlex
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from planner.db.store import Database, ObjectRow
from planner.errors import InputError, UnknownNameError
from planner.specs.objects import (  # noqa: F401 - PROPERTY_RTOL re-exported
    PROPERTY_RTOL,
    ObjectSpec,
    file_named,
    is_registered,
    resolve_spec,
)

if TYPE_CHECKING:
    from planner.geometry.solid import PreparedObject

DEFAULT_DB = Path("grasps.db")
#: A typed quaternion whose norm lies outside this range is a mistake (a component missing or wrong; the w-first
#: order of another tool is still unit: see the troubleshooting table), not a rotation typed with few digits
#: (0,0,0.7,0.7: 0.99); inside it, it is normalised.
QUATERNION_NORM = (0.9, 1.1)
#: [m] A typed position farther than this from the origin is a mistake (an arm reaches metres); beyond it the
#: reachability search would run on numbers too large for it (1e308 ran for more than 10 minutes).
MAX_DISTANCE = 1000.0
#: Stored object names an "unknown object" error lists at most.
LISTED_NAMES = 12


def resolve_object(db: Database, name: str) -> tuple[str, ObjectRow | None]:
    """The database's name and ``objects`` row of the object ``name`` means.

    ``name`` is a stored object's name (any object with grasps: built-in,
    ``random_NNN``, a user mesh or URDF by its stem or label, an imported
    object, a mesh generated with ``--scale``), else a built-in name or
    ``random_NNN``, named as ``generate`` names it, or a mesh or URDF path:
    the object stored from that file (:func:`_from_file`). The row (None when the object
    is not stored) holds the source, scale, mass and friction its grasps were
    planned with: :func:`~planner.db.objects.stored_object` rebuilds it.
    """
    row = db.object_row(name)
    if row is not None:
        return name, row
    file = file_named(name)
    if file is not None:  # by its file alone: its own values may be refused now (a URDF's mass 0 given --mass)
        return _from_file(db, name, Path(name).stem, str(file))
    try:
        spec = resolve_spec(name)
    except UnknownNameError:
        stored = sorted({o for o, _ in db.pairs()})
        listed = ", ".join(stored[:LISTED_NAMES]) + (f", ... ({len(stored)} in all)" if len(stored) > LISTED_NAMES
                                                     else "")
        raise InputError(f"unknown object '{name}': not stored in {db.path} (objects: {listed or 'none'}) and not "
                         f"a built-in name, random_NNN or mesh file (see `grasp objects`)") from None
    return spec.name, db.object_row(spec.name)


def _from_file(db: Database, name: str, key: str, source: str) -> tuple[str, ObjectRow | None]:
    """The object the mesh file ``name`` (``source``, resolved) means in ``db``: the one ``generate`` stores it
    as (its stem ``key`` at scale 1), else the one object stored from that file (a manifest's scale, a name with
    folders); several of them are named for the user to pick one. An object of that name from another file that
    is here is not this file's."""
    rows = [r for r in map(db.object_row, db.objects_from(source)) if r is not None]
    own = next((r for r in rows if r.name == key and r.scale == 1.0), None)
    if own is not None or len(rows) == 1:
        found = own or rows[0]
        return found.name, found
    if rows:
        listed = ", ".join(f"'{r.name}' (scale {r.scale:g})" for r in rows)
        raise InputError(f"{name} is stored in {db.path} as {len(rows)} objects, {listed}: give the object's name")
    row = db.object_row(key)
    if row is not None and Path(row.source).is_file() and Path(row.source) != Path(source):
        raise InputError(f"{name} is not stored in {db.path}: its object '{key}' is another file, {row.source}; "
                         f"plan {name} into another --db (`grasp generate {shlex.quote(name)} --hand H --db ...`)")
    return key, row


def _stored(db: Database, name: str, hand: str, doing: str) -> tuple[str, PreparedObject]:
    """Name and rebuilt object of a stored object, for ``doing`` with ``hand``'s
    geometry (refused where the hand was edited since its grasps were stored:
    :func:`planner.db.hand_files.refuse_edited`); an object without grasps is an error."""
    from planner.db.hand_files import refuse_edited
    from planner.db.objects import stored_object

    refuse_edited(db, hand, doing)

    key, row = resolve_object(db, name)
    if row is None:
        raise InputError(f"no grasps of '{key}' for hand '{hand}' in {db.path}; "
                         f"run `{generate_command(name, row, hand, db.path)}`")
    return key, stored_object(row)


def generate_command(name: str, row: ObjectRow | None, hand: str, db_path: Path) -> str:
    """The ``grasp generate`` command that plans the object ``name`` means
    for ``hand``: a stored mesh by its file (its name alone is no object),
    with the stored scale, mass, friction and up where the file does not give them."""
    db = "" if Path(db_path) == DEFAULT_DB else f" --db {shlex.quote(str(db_path))}"
    if row is None or is_registered(row.name) or not Path(row.source).is_file():
        up = "" if row is None or row.up == "+z" else f" --up {row.up}"
        return f"grasp generate {shlex.quote(name)} --hand {hand}{up}{db}"
    scale = None if row.scale == 1.0 else row.scale
    try:
        own: ObjectSpec | None = resolve_spec(row.source, scale=scale)
    except InputError:  # the file alone is refused (a URDF's mass 0, its links' frictions apart): each stored value
        own = None
    extra = "" if scale is None else f" --scale {scale!r}"
    if own is None or own.density is None and not math.isclose(own.mass, row.mass, rel_tol=PROPERTY_RTOL):
        extra += f" --mass {row.mass!r}"
    if own is not None and own.density is not None and not math.isclose(own.density, row.density,
                                                                        rel_tol=PROPERTY_RTOL):
        extra += f" --density {row.density!r}"
    if own is None or not math.isclose(own.friction, row.friction, rel_tol=PROPERTY_RTOL):
        extra += f" --friction {row.friction!r}"
    if own is None or own.up != row.up:
        extra += f" --up {row.up}"
    return f"grasp generate {shlex.quote(row.source)} --hand {hand}{extra}{db}"


def object_pose_matrix(values: Sequence[float]) -> np.ndarray:
    """(4, 4) the pose ``--object-pose`` x,y,z,qx,qy,qz,qw gives (checked)."""
    return _pose7(values, "--object-pose")


def _pose7(values: Sequence[float], option: str) -> np.ndarray:
    from planner.geometry.frames import pose_from_xyzquat

    try:
        vals = [float(v) for v in values]
    except (TypeError, ValueError):  # a 4x4 matrix, a string
        got = f"an array of shape {np.shape(values)}" if isinstance(values, np.ndarray) else repr(values)
        raise InputError(f"{option} needs 7 finite numbers x,y,z,qx,qy,qz,qw; got {got}") from None
    if len(vals) != 7 or not all(np.isfinite(vals)):
        raise InputError(f"{option} needs 7 finite numbers x,y,z,qx,qy,qz,qw; got {values}")
    if math.hypot(*vals[:3]) > MAX_DISTANCE:
        raise InputError(f"{option}: position {vals[:3]} lies more than {MAX_DISTANCE:g} m from the origin; give "
                         "metres")
    q = np.array(vals[3:])
    lo, hi = QUATERNION_NORM
    if not lo < np.linalg.norm(q) < hi:
        raise InputError(f"{option}: quaternion {vals[3:]} has length {np.linalg.norm(q):.4g}, not 1 (within "
                         f"{hi - 1:.0%}); give x,y,z,qx,qy,qz,qw with a unit quaternion")
    vals[3:] = list(q / np.linalg.norm(q))
    return pose_from_xyzquat(vals)
