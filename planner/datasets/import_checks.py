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
from planner.specs.objects import PROPERTY_RTOL

if TYPE_CHECKING:
    from planner.datasets.importer import _Plan as Plan


def check_objects(db: Database, plans: Sequence[Plan]) -> None:
    """One name, one object, before anything is written: a file's object against the one the database stores under
    its name (mesh, mass properties, mass and friction; :func:`planner.db.objects.differs`) and against the other
    files' of this import that name it."""
    from planner.db.objects import differs

    named: dict[str, tuple[Path, PreparedObject]] = {}
    for plan in plans:
        name = plan.spec.name
        obj = prepare(plan.spec)
        row = db.object_row(name)
        why = differs(row, obj) if row is not None else None
        if why:
            raise InputError(f"{plan.path}: object '{name}' is stored in {db.path} {why}: import into another --db")
        done = (name, 0) in db.units_done(plan.hand.name, plan.settings.digest, 0)  # imported before: skipped
        if row is not None and plan.lossless and not done:
            check_not_stored(db, plan)
        first = named.setdefault(name, (plan.path, obj))
        if first[1].mesh_hash != obj.mesh_hash or not math.isclose(first[1].mass, obj.mass, rel_tol=PROPERTY_RTOL):
            raise InputError(f"{plan.path} and {first[0]} name one object '{name}' with other meshes, scales or "
                             "masses: import them into different --db")


def check_not_stored(db: Database, plan: Plan) -> None:
    """Refuse a file whose grasps the database holds already (an export of it, imported back: each one twice)."""
    stored = [g.pose for batch in db.grasp_batches(plan.spec.name, plan.hand.name) for g in batch]
    poses = plan.reader.poses(plan.path, plan.hand)
    again = int(same_poses(poses, np.reshape(stored, (-1, 4, 4))).sum())
    if again:
        raise InputError(f"{plan.path}: {again} of its {len(poses)} grasps are stored in {db.path} already "
                         f"('{plan.spec.name}', {plan.hand.name}): an export of this database? Import it into "
                         "another --db")
