"""The object on the table: the ``grasp generate --on-table`` command for
it, whether grasps were planned on the table in a given resting pose, and
:func:`best_on_table`, the grasps an arm reaches in each of its most
probable resting poses (:class:`TableGrasps`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from planner.api.reaching import MAX_CANDIDATES, ReachableGrasp, _closures, _plan_now, _preferred, _reachable
from planner.api.resolving import DEFAULT_DB, _pose7, _stored, generate_command, resolve_object
from planner.db.store import open_db
from planner.errors import InputError
from planner.specs.hands import load_hand

if TYPE_CHECKING:
    from planner.geometry.stable import RestingPose


TABLE_AT = (0.5, 0.0)  # [m] where --on-table puts the object, robot base frame


def table_command(name: str, hand: str, db_path: Path = DEFAULT_DB) -> str:
    """The ``grasp generate --on-table`` command that plans the object's
    grasps on the table in its most probable resting poses."""
    with open_db(Path(db_path), create=False, readonly=True) as db:
        _, row = resolve_object(db, name)
    return generate_command(name, row, hand, Path(db_path)) + " --on-table"


def planned_on_table(name: str, hand: str, object_pose: Sequence[float], *, db_path: Path = DEFAULT_DB,
                     table_height: float = 0.0) -> bool:
    """Are grasps of the object stored that were planned on the table as it
    lies at ``object_pose`` (the same resting pose, :func:`planner.geometry.support.nearest`)?"""
    from planner.geometry.support import Support, nearest

    pose = _pose7(object_pose, "--object-pose")
    with open_db(Path(db_path), create=False, readonly=True) as db:
        key, _ = resolve_object(db, name)
        return nearest(db.table_planes(key, hand), Support.under(pose, table_height)) is not None


@dataclass(frozen=True)
class TableGrasps:
    """The grasps an arm reaches with the object in one of its resting poses."""

    resting: RestingPose
    object_pose: np.ndarray  # (4, 4) the object frame in the world [m]
    grasps: list[ReachableGrasp]
    misses: list[tuple[int, str]]

    def object_pose7(self) -> list[float]:
        """x, y, z, qx, qy, qz, qw, as ``--object-pose`` takes it (no ``-0.0``: + 0.0 makes it 0.0, changing no other
        value, so the printed ``--object-pose`` reads as typed)."""
        from planner.geometry.quaternion import canonical_xyzw

        seven = [*self.object_pose[:3, 3].tolist(), *canonical_xyzw(self.object_pose[:3, :3]).tolist()]
        return [v + 0.0 for v in seven]

    def to_json(self) -> dict:
        return {"resting_probability": self.resting.probability, "object_pose": self.object_pose7(),
                "grasps": [r.to_json() for r in self.grasps]}


def best_on_table(name: str, hand: str, *, db_path: Path = DEFAULT_DB, top: int = 1, at: Sequence[float] = TABLE_AT,
                  table_height: float = 0.0, poses: int = 3, robot_base: Sequence[float] | None = None,
                  max_candidates: int = MAX_CANDIDATES, seed: int = 0, plan: bool = True) -> list[TableGrasps]:
    """The best reachable grasps with the object resting on the table at
    ``at`` = (x, y) [m] (world frame), in each of its ``poses`` most probable
    resting poses (:mod:`planner.geometry.stable`), most probable first; in
    each, as :func:`best_at` finds them (stored grasps planned on the table
    in that pose first, then the rest; with ``plan``, grasps planned on the
    spot if fewer than ``top`` are reachable)."""
    from planner.geometry.stable import resting_poses
    from planner.plan.reach import ReachScene, ReachSettings
    from planner.sim import Sim

    if top < 1 or poses < 1 or max_candidates < 0:
        raise InputError(f"--top and --stable-poses must be at least 1 and --max-candidates at least 0, got {top}, "
                         f"{poses} and {max_candidates}")
    xy = [float(v) for v in at]
    if len(xy) != 2 or not all(np.isfinite(xy)) or not np.isfinite(table_height):
        raise InputError(f"--table-at needs 2 finite numbers x,y [m]; got {at}")
    base = _pose7(robot_base, "--robot-base") if robot_base is not None else np.eye(4)
    spec = load_hand(hand)
    out = []
    with open_db(Path(db_path), create=False, readonly=True) as db, db.snapshot(), Sim() as sim:
        key, obj = _stored(db, name, hand, "the table check")
        scene = ReachScene(sim, spec, obj, ReachSettings(table_height=table_height), base)
        for resting in resting_poses(obj.mesh, obj.com, poses):
            pose = resting.placed(xy[0], xy[1], table_height)
            rng = np.random.default_rng(seed)  # each pose as best_at(..., seed) finds it: its --object-pose repeats it
            misses: list[tuple[int, str]] = []
            found = _reachable(db, scene, key, hand, pose, top, max_candidates, rng, misses)
            if plan and _closures(found) < top:
                found = _preferred(found, _plan_now(db, scene, obj, pose, top, seed, rng, misses), top)
            out.append(TableGrasps(resting, pose, found, misses))
    return out
