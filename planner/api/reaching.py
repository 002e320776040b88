"""Grasps an arm reaches *now*: :func:`best_at` tries stored grasps in rank
order (those planned on the table in the object's resting pose first) with
the object at a given pose, and plans more on the spot with the table under
the object (:data:`PLAN_NOW`) when too few are reached; each found one is a
:class:`ReachableGrasp`.
"""

from __future__ import annotations

import itertools
import logging
import math
import shlex
import time
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from planner.api.resolving import DEFAULT_DB, _pose7, _stored, generate_command
from planner.db.store import Database, open_db
from planner.errors import InputError
from planner.plan.sweep import SweepSettings
from planner.plan.tolerances import PREGRASP_DISTANCE
from planner.record.grasp import Grasp
from planner.specs.hands import HandSpec, load_hand

if TYPE_CHECKING:
    from planner.geometry.solid import PreparedObject
    from planner.plan.reach import ReachScene

#: The facade's logger (``planner.api``), the name these messages have always carried.
log = logging.getLogger(__package__)

#: ``best_at`` reads stored grasps in rank order this many at a time.
CANDIDATE_BATCH = 50
#: ``best_at`` tries at most this many top-ranked grasps by default.
MAX_CANDIDATES = 300
#: [m] How far below the table top an object at ``--object-pose`` may reach (round-off of a typed resting pose)
#: before the pose is refused as one that puts the object through the table.
BELOW_TABLE = 1e-3


@dataclass(frozen=True)
class ReachableGrasp:
    """A grasp with the arm solutions that reach it at a given pose: a stored
    one, or (``planned_now``) one the query planned on the spot with the
    table under the object (not stored: no id, no rank)."""

    grasp: Grasp
    arm_grasp: dict[str, float]  # arm joint values [rad] at the grasp
    arm_pregrasp: dict[str, float]  # ... and at the pre-grasp
    manipulability: float
    hand_pose_world: list[list[float]]  # (4, 4) where the hand frame ends up [m]
    planned_now: bool = False

    def to_json(self) -> dict:
        return {**self.grasp.to_json(), "arm": {"grasp": self.arm_grasp, "pregrasp": self.arm_pregrasp},
                "arm_manipulability": self.manipulability, "hand_pose_world": self.hand_pose_world,
                "planned_now": self.planned_now}


def best_at(name: str, hand: str, object_pose: Sequence[float], *, db_path: Path = DEFAULT_DB, top: int = 1,
            robot_base: Sequence[float] | None = None, max_candidates: int = MAX_CANDIDATES,
            pregrasp_distance: float = PREGRASP_DISTANCE, seed: int = 0,
            misses: list[tuple[int, str]] | None = None, plan: bool = True) -> list[ReachableGrasp]:
    """The best grasps that an arm reaches *now*, with the object at
    ``object_pose`` (x, y, z, qx, qy, qz, qw, world frame) on the table top
    z = 0 and the robot base at ``robot_base`` (same form; default the
    origin): the ``top`` best-ranked stored grasps it reaches, of at most
    ``max_candidates`` tried (:func:`_reachable`: those planned on the table
    in this resting pose first, then better-ranked others); if fewer than
    ``top`` of them rank first (force closure as planned or once squeezed) and ``plan``, grasps are also planned
    on the spot with the table under the object (:func:`_plan_now`, from
    ``seed``), and the ones that rank first come first (:func:`_preferred`). ``misses``, if
    given, receives (rank, why) of each one tried and not reachable (rank 0:
    planned on the spot)."""
    from planner.plan.reach import ReachScene, ReachSettings
    from planner.sim import Sim

    if top < 1 or max_candidates < 0:
        raise InputError(f"--top must be at least 1 and --max-candidates at least 0, got {top} and {max_candidates}")
    if not (math.isfinite(pregrasp_distance) and pregrasp_distance >= 0):
        raise InputError(f"pregrasp_distance must be a finite distance >= 0 [m], got {pregrasp_distance}")
    obj_pose = _pose7(object_pose, "--object-pose")
    base = _pose7(robot_base, "--robot-base") if robot_base is not None else np.eye(4)
    spec = load_hand(hand)
    missed = misses if misses is not None else []
    with open_db(Path(db_path), create=False, readonly=True) as db, db.snapshot(), Sim() as sim:
        key, obj = _stored(db, name, hand, "the reach check")
        settings = ReachSettings(pregrasp_distance=pregrasp_distance)
        lowest = float((obj.mesh.vertices @ obj_pose[:3, :3].T)[:, 2].min() + obj_pose[2, 3])
        if lowest < settings.table_height - BELOW_TABLE:
            raise InputError(f"--object-pose puts {key} through the table: its lowest point at z = {lowest:.4f} m, "
                             f"{(settings.table_height - lowest) * 1000:.1f} mm below the table top z = "
                             f"{settings.table_height:g} (the pose is of the object frame, the mesh's; `grasp best "
                             f"{shlex.quote(key)} --hand {hand} --db {shlex.quote(str(db_path))} --on-table` gives "
                             "its resting poses on the table)")
        scene = ReachScene(sim, spec, obj, settings, base)
        rng = np.random.default_rng(seed)
        found = _reachable(db, scene, key, hand, obj_pose, top, max_candidates, rng, missed)
        if plan and _closures(found) < top:
            found = _preferred(found, _plan_now(db, scene, obj, obj_pose, top, seed, rng, missed), top)
        return found


def _first(found: Sequence[ReachableGrasp]) -> list[bool]:
    """Which of ``found`` rank first (:func:`planner.db.ranking.ranks_first`: force closure as planned or once a
    parallel jaw's squeeze turns the object, unless that squeeze's end is kept beside it), as the database ranks
    them."""
    from planner.db.ranking import first_of

    return first_of([r.grasp for r in found])


def _closures(found: Sequence[ReachableGrasp]) -> int:
    return sum(_first(found))


def _preferred(stored: list[ReachableGrasp], planned: list[ReachableGrasp], top: int) -> list[ReachableGrasp]:
    """The ``top`` to return of reachable stored grasps (rank order) and grasps
    planned on the spot (best first): those that rank first (:func:`_first`) first, stored before
    planned."""
    both = [*stored, *planned]
    first = _first(both)
    return [both[i] for i in sorted(range(len(both)), key=lambda i: not first[i])][:top]  # stable: keeps each order


def _reachable(db: Database, scene: ReachScene, key: str, hand: str, obj_pose: np.ndarray, top: int,
               max_candidates: int, rng: np.random.Generator, misses: list[tuple[int, str]]) -> list[ReachableGrasp]:
    """The ``top`` best-ranked stored grasps the scene's arm reaches with the
    object at ``obj_pose`` (4, 4), of at most ``max_candidates`` tried, best
    first; misses noted as (rank, why). Without grasps planned on the table
    in this resting pose (:func:`planner.geometry.support.nearest`), every
    grasp in rank order. With them: those first, in rank order (most are
    reachable: a few tries find ``top``); then the others (planned on the
    object alone or on another plane), in rank order, only those ranked above
    the worst found so far -- the ones that could still make the ``top``."""
    from planner.geometry.support import Support, nearest

    plane = nearest(db.table_planes(key, hand), Support.under(obj_pose, scene.settings.table_height))
    if plane is None:
        found, tried = _first_reached(scene, _ranked(db, key, hand), obj_pose, top, max_candidates, rng, misses)
    else:
        found, tried = _first_reached(scene, _ranked(db, key, hand, table_plane=plane), obj_pose, top,
                                      max_candidates, rng, misses)
        others = _ranked(db, key, hand, table_plane=plane, other_planes=True)
        if len(found) == top:
            bound = found[-1].grasp.rank or 0
            others = itertools.takewhile(lambda g: (g.rank or 0) < bound, others)
        more, extra = _first_reached(scene, others, obj_pose, top, max_candidates - tried, rng, misses)
        found = sorted(found + more, key=lambda r: r.grasp.rank or 0)[:top]
        tried += extra
    if tried == 0 and max_candidates > 0:
        raise InputError(f"no grasps of '{key}' for hand '{hand}' in {db.path}; "
                         f"run `{generate_command(key, db.object_row(key), hand, db.path)}`")
    return found


def _ranked(db: Database, key: str, hand: str, **which: Any) -> Iterator[Grasp]:
    """Stored grasps of (key, hand) in rank order, read in batches; ``which``:
    :meth:`Database.best`'s ``table_plane`` and ``other_planes``."""
    offset = 0
    while batch := db.best(key, hand, CANDIDATE_BATCH, offset, **which):
        offset += len(batch)
        yield from batch


def _first_reached(scene: ReachScene, grasps: Iterable[Grasp], obj_pose: np.ndarray, top: int, max_candidates: int,
                   rng: np.random.Generator, misses: list[tuple[int, str]], planned_now: bool = False
                   ) -> tuple[list[ReachableGrasp], int]:
    """The first ``top`` of at most ``max_candidates`` of ``grasps``, in their
    order, that the scene's arm reaches with the object at ``obj_pose`` (4,
    4), and how many were tried; misses noted as (rank, why), rank 0 for a
    grasp not stored."""
    scene.place_object(obj_pose)
    found: list[ReachableGrasp] = []
    tried = 0
    for g in grasps:
        if len(found) == top or tried == max_candidates:
            break
        tried += 1
        if not g.score:
            misses.append((g.rank or 0, "score 0 (gated out by the ranking rule)"))
            continue
        reach = scene.check(g.pose, g.closed_joints, g.open_joints, rng)
        if reach.grasp is not None and reach.pregrasp is not None:
            found.append(ReachableGrasp(g, reach.grasp.joints, reach.pregrasp.joints,
                                        reach.grasp.manipulability, (obj_pose @ g.pose).tolist(), planned_now))
        else:
            misses.append((g.rank or 0, reach.why))
    return found, tried


def _plan_now(db: Database, scene: ReachScene, obj: PreparedObject, obj_pose: np.ndarray, top: int, seed: int,
              rng: np.random.Generator, misses: list[tuple[int, str]]) -> list[ReachableGrasp]:
    """Plan grasps on the spot with the table under the object at
    ``obj_pose`` (:data:`PLAN_NOW`, seeded by ``seed``; not stored), score
    them as ``db`` would, and return the first ``top`` the arm reaches, best
    first; misses noted with rank 0."""
    from planner.geometry.support import Support
    from planner.plan.unit import plan_object

    hand = scene.hand
    start = time.process_time()
    settings = plan_now_settings(hand).on(Support.under(obj_pose, scene.settings.table_height))
    result = plan_object(obj, hand.name, settings, seed)
    grasps = db.scored(result.grasps, hand.name)
    found, tried = _first_reached(scene, grasps, obj_pose, top, len(grasps), rng, misses, planned_now=True)
    log.info("planned on the spot with the table: %d candidates, %d grasps, %d reachable of %d tried (%.1f CPU s)",
             result.candidates, len(grasps), len(found), tried, time.process_time() - start)
    if not grasps:
        misses.append((0, f"planned on the spot with the table: none of {result.candidates} candidates closed on "
                          "the object"))
    return found


#: The sweep ``grasp best --object-pose`` / ``--on-table`` runs on the spot
#: when no stored grasp is reachable: per sampler, approaches and rolls (a
#: fraction of the default sweep: seconds, not minutes), one unit, no
#: stored reachability (the query checks reach exactly), and a force-closure
#: budget that ends it once it has found enough.
PLAN_NOW = {"surface": {"approaches": 24, "rolls": 2}, "box": {"rolls": 2},
            "antipodal": {"approaches": 256, "rolls": 8}}
PLAN_NOW_BUDGET = 40


def plan_now_settings(hand: HandSpec) -> SweepSettings:
    """The sweep of :data:`PLAN_NOW` for ``hand`` (before the table plane is set)."""
    return SweepSettings(chunk=0, reach_placements=0, fc_budget=PLAN_NOW_BUDGET,
                         **PLAN_NOW[hand.sampler]).resolved(hand.sampler, hand.settle, hand.settle_dynamics)
