"""What ``grasp import`` checks in the database before it writes anything (:mod:`planner.datasets.importer`):
one name, one object; a file's grasps not stored there already."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from planner.db.store import Database
from planner.errors import InputError
from planner.geometry.frames import same_poses
from planner.geometry.solid import PreparedObject, prepare
from planner.record.field import same_inertial
from planner.specs.objects import PROPERTY_RTOL

if TYPE_CHECKING:
    from planner.datasets.importer import _Plan as Plan


def check_files(plans: Sequence[Plan]) -> list[PreparedObject]:
    """One name, one object among the files of this import (mesh, scale, mass, friction, up), before the database is
    opened: a refused import leaves no empty database at --db. Each file's object, in the order of ``plans``."""
    objs = [prepare(plan.spec) for plan in plans]
    named: dict[str, tuple[Path, PreparedObject]] = {}
    for plan, obj in zip(plans, objs):
        first = named.setdefault(plan.spec.name, (plan.path, obj))
        why = _apart(obj, first[1])  # its values in the order the paths are said
        if why:
            raise InputError(f"{plan.path} and {first[0]} name one object '{plan.spec.name}' with {why}: import them "
                             "into different --db")
    return objs


def check_objects(db: Database, plans: Sequence[Plan], objs: Sequence[PreparedObject]) -> None:
    """One name, one object, before anything is written: a file's object (``objs``, :func:`check_files`') against
    the one the database stores under its name (mesh, mass properties, mass and friction;
    :func:`planner.db.objects.differs`)."""
    from planner.db.objects import differs

    for plan, obj in zip(plans, objs):
        name = plan.spec.name
        row = db.object_row(name)
        why = differs(row, obj) if row is not None else None
        if why:
            raise InputError(f"{plan.path}: object '{name}' is stored in {db.path} {why}: import into another --db")
        done = (name, 0) in db.units_done(plan.hand.name, plan.settings.digest, 0)  # imported before: skipped
        if row is not None and plan.lossless and not done:
            check_not_stored(db, plan)


def _apart(first: PreparedObject, obj: PreparedObject) -> str | None:
    """How two files' objects of one name differ, ``first``'s value said first (None: they do not): a copy of one
    file read beside a sidecar of another friction, up or centre of mass was taken at the first's without a word."""
    if first.mesh_hash != obj.mesh_hash or not math.isclose(first.mass, obj.mass, rel_tol=PROPERTY_RTOL):
        return "other meshes, scales or masses"
    if not math.isclose(first.friction, obj.friction, rel_tol=PROPERTY_RTOL):
        return f"friction {first.friction:g} and {obj.friction:g}"
    if first.spec.up != obj.spec.up:
        return f"up {first.spec.up} and {obj.spec.up}"
    if not same_inertial(first.com, first.inertia, obj.com, obj.inertia):  # a sidecar's com (or a URDF's inertia)
        return f"centres of mass {_point(first.com)} and {_point(obj.com)} m (or other inertias)"
    return None


def _point(values: np.ndarray) -> str:
    """A centre of mass (3,) [m] as said: to 0.1 um (a mesh's own centre at 1e-17 said 0), no negative zeros."""
    return "[" + ", ".join(f"{v:.4g}" for v in np.round(np.ravel(values), 7) + 0.0) + "]"


def check_not_stored(db: Database, plan: Plan) -> None:
    """Refuse a file whose grasps the database holds already (an export of it, imported back: each one twice)."""
    stored = [g.pose for batch in db.grasp_batches(plan.spec.name, plan.hand.name) for g in batch]
    poses = plan.reader.poses(plan.path, plan.hand)
    again = int(same_poses(poses, np.reshape(stored, (-1, 4, 4))).sum())
    if again:
        raise InputError(f"{plan.path}: {again} of its {len(poses)} grasps are stored in {db.path} already "
                         f"('{plan.spec.name}', {plan.hand.name}): an export of this database? Import it into "
                         "another --db")
