"""The Python API; the ``grasp`` CLI only wraps these functions."""

from __future__ import annotations

import logging
import os
import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from planner.db.lock import writer_lock
from planner.db.ranking import RankingRule
from planner.db.store import Database, GraspRow, open_db
from planner.db.writer import apply_rule, write_unit
from planner.errors import InputError
from planner.geometry.solid import load_object
from planner.plan.sweep import SweepSettings
from planner.plan.unit import UnitResult, UnitSpec
from planner.specs.hands import load_hand
from planner.specs.objects import resolve_spec

log = logging.getLogger(__name__)

DEFAULT_DB = Path("grasps.db")


@dataclass
class Summary:
    """What a ``generate`` run did."""

    units: int = 0
    skipped: int = 0
    failed: dict[str, str] = field(default_factory=dict)
    candidates: int = 0
    grasps: int = 0
    force_closure: int = 0
    rejected: Counter = field(default_factory=Counter)
    seconds: float = 0.0
    per_object: list[dict] = field(default_factory=list)

    def to_json(self) -> dict:
        return {"units": self.units, "skipped": self.skipped, "failed": self.failed, "candidates": self.candidates,
                "grasps": self.grasps, "force_closure": self.force_closure, "rejected": dict(self.rejected),
                "seconds": round(self.seconds, 3), "objects": self.per_object}


def plan_units(names: Sequence[str], hand: str, settings: SweepSettings, seed: int,
               scale: float | None = None) -> list[UnitSpec]:
    """Expand the object arguments and check every input up front (names,
    hand, preshapes) before any work."""
    from planner.specs.inputs import expand
    from planner.specs.preshapes import load_preshapes

    refs = expand(list(names), scale)
    if not refs:
        raise InputError("no objects given")
    hand_spec = load_hand(hand)
    load_preshapes(hand_spec, list(settings.preshapes) if settings.preshapes else None)
    units, seen = [], set()
    for ref in refs:
        spec = resolve_spec(ref.source, scale=ref.scale, label=ref.label)
        if spec.kind == "mesh" and not spec.source.startswith("pybullet_data:") and not Path(spec.source).exists():
            raise InputError(f"{spec.source}: file not found")
        if spec.name in seen:
            continue
        seen.add(spec.name)
        units += [UnitSpec(ref.source, hand, settings, seed, ref.scale, chunk, label=spec.name)
                  for chunk in range(settings.chunks())]
    if len(refs) == 1:
        # One object: a broken mesh is the user's input error, reported before
        # the database is opened. In a batch it is recorded and the rest go on.
        load_object(refs[0].source, scale=refs[0].scale)
    return units


def generate(names: Sequence[str], hand: str, *, db_path: Path = DEFAULT_DB, settings: SweepSettings | None = None,
             seed: int = 0, workers: int = 1, scale: float | None = None, rule: RankingRule | None = None,
             use_ray: bool = False, ray_address: str | None = None, unit_timeout: float | None = None,
             progress: Callable[[UnitResult, int, int], None] | None = None) -> Summary:
    """Build (or extend) a grasp database; finished units are skipped."""
    settings = settings or SweepSettings()
    units = plan_units(names, hand, settings, seed, scale)
    summary = Summary()
    start = time.perf_counter()
    with writer_lock(Path(db_path)), open_db(Path(db_path)) as db:
        rule = rule or RankingRule.from_json(db.meta("ranking"))
        apply_rule(db, rule)
        todo = []
        done = db.units_done(hand, settings.digest, seed)
        for unit in units:
            if (unit.label, unit.chunk) in done:
                summary.skipped += 1
            else:
                todo.append(unit)
        if progress:
            progress(None, 0, len(todo))  # type: ignore[arg-type]
        if unit_timeout:
            from dataclasses import replace

            todo = [replace(u, timeout=unit_timeout) for u in todo]
        from planner.plan.pool import execute

        for done_count, (result, seconds) in enumerate(execute(todo, workers, ray_address, use_ray), start=1):
            write_unit(db, result, seconds, rule)
            _tally(summary, result, seconds)
            if progress:
                progress(result, done_count, len(todo))
    summary.seconds = time.perf_counter() - start
    return summary


def _tally(summary: Summary, result: UnitResult, seconds: float) -> None:
    summary.units += 1
    name = result.obj.name if result.obj else (result.spec.label or result.spec.object_name)
    if result.error:
        summary.failed[name] = result.error
    summary.candidates += result.candidates
    summary.grasps += len(result.grasps)
    summary.force_closure += result.force_closure
    summary.rejected.update(result.rejected)
    row = next((r for r in summary.per_object if r["object"] == name), None)
    if row is None:
        row = {"object": name, "units": 0, "candidates": 0, "grasps": 0, "force_closure": 0, "seconds": 0.0,
               "error": None}
        summary.per_object.append(row)
    row["units"] += 1
    row["candidates"] += result.candidates
    row["grasps"] += len(result.grasps)
    row["force_closure"] += result.force_closure
    row["seconds"] = round(row["seconds"] + seconds, 3)
    row["error"] = row["error"] or result.error


def best(name: str, hand: str, *, db_path: Path = DEFAULT_DB, top: int = 1) -> list[GraspRow]:
    """The ``top`` best grasps of an object for a hand, in rank order."""
    if top < 1:
        raise InputError(f"--top must be at least 1, got {top}")
    load_hand(hand)
    key = resolve_spec(name).name
    with open_db(Path(db_path), create=False, readonly=True) as db:
        rows = db.best(key, hand, top)
        if not rows:
            known = db.objects_for(hand)
            raise InputError(f"no grasps of '{key}' for hand '{hand}' in {db_path}; objects with grasps: "
                             f"{', '.join(known) or '(none)'}; run `grasp generate {name} --hand {hand}`")
    return rows


@dataclass(frozen=True)
class ReachableGrasp:
    """A stored grasp with the arm solutions that reach it at a given pose."""

    grasp: GraspRow
    arm_grasp: dict[str, float]  # arm joint values [rad] at the grasp
    arm_pregrasp: dict[str, float]  # ... and at the pre-grasp
    manipulability: float
    hand_pose_world: list[list[float]]  # (4, 4) where the hand frame ends up [m]


def best_at(name: str, hand: str, object_pose: Sequence[float], *, db_path: Path = DEFAULT_DB, top: int = 1,
            robot_base: Sequence[float] | None = None, max_candidates: int = 300,
            pregrasp_distance: float = 0.10, seed: int = 0) -> list[ReachableGrasp]:
    """The best stored grasps that an arm reaches *now*, with the object at
    ``object_pose`` (x, y, z, qx, qy, qz, qw, world frame) and the robot base at
    ``robot_base`` (same form; default the origin). Candidates are tried in
    rank order, at most ``max_candidates`` of them."""
    import numpy as np

    from planner.plan.reach import ReachScene, ReachSettings
    from planner.sim import Sim

    if top < 1:
        raise InputError(f"--top must be at least 1, got {top}")
    obj_pose = _pose7(object_pose, "--object-pose")
    base = _pose7(robot_base, "--robot-base") if robot_base is not None else np.eye(4)
    spec = load_hand(hand)
    key = resolve_spec(name).name
    obj = load_object(name)
    rng = np.random.default_rng(seed)
    found: list[ReachableGrasp] = []
    with open_db(Path(db_path), create=False, readonly=True) as db, Sim() as sim:
        scene = ReachScene(sim, spec, obj, ReachSettings(pregrasp_distance=pregrasp_distance), base)
        scene.place_object(obj_pose)
        offset = 0
        while len(found) < top and offset < max_candidates:
            batch = db.best(key, hand, min(50, max_candidates - offset), offset)
            if not batch:
                break
            offset += len(batch)
            for row in batch:
                if not row.force_closure:
                    continue
                pose = np.array(row.pose)
                reach = scene.check(pose, row.closed_joints, row.open_joints, rng)
                if reach.reachable:
                    found.append(ReachableGrasp(row, reach.grasp.joints, reach.pregrasp.joints,  # type: ignore[union-attr]
                                                reach.grasp.manipulability,  # type: ignore[union-attr]
                                                (obj_pose @ pose).tolist()))
                    if len(found) == top:
                        break
        if offset == 0:
            raise InputError(f"no grasps of '{key}' for hand '{hand}' in {db_path}; "
                             f"run `grasp generate {name} --hand {hand}`")
    return found


def _pose7(values: Sequence[float], option: str):  # type: ignore[no-untyped-def]
    import numpy as np

    from planner.geometry.frames import pose_from_xyzquat

    vals = [float(v) for v in values]
    if len(vals) != 7 or not all(np.isfinite(vals)):
        raise InputError(f"{option} needs 7 finite numbers x,y,z,qx,qy,qz,qw; got {values}")
    q = np.array(vals[3:])
    if not 0.5 < np.linalg.norm(q) < 2.0:
        raise InputError(f"{option}: quaternion {vals[3:]} is not close to unit length")
    vals[3:] = list(q / np.linalg.norm(q))
    return pose_from_xyzquat(tuple(vals))


def show(name: str, hand: str, out: Path, *, db_path: Path = DEFAULT_DB, rank: int = 1, top: int | None = None
         ) -> list[GraspRow]:
    """Render grasp ``rank`` (or the ``top`` K as a contact sheet) to a PNG."""
    from planner.present import render

    count = top or 1
    first = 1 if top else rank
    if count < 1 or first < 1:
        raise InputError("--rank and --top must be at least 1")
    spec = load_hand(hand)
    key = resolve_spec(name).name
    with open_db(Path(db_path), create=False, readonly=True) as db:
        rows = db.best(key, hand, count, first - 1)
    if not rows:
        raise InputError(f"no grasp of rank {first} for '{key}' and hand '{hand}' in {db_path}")
    if Path(out).suffix.lower() != ".png":
        raise InputError(f"{out}: the picture is written as PNG; give a .png path")
    obj = load_object(name)
    render.save_sheet([(render.grasp_views(spec, obj, row), render.title(row)) for row in rows], Path(out))
    return rows


def check_db(db_path: Path) -> list[str]:
    """``PRAGMA integrity_check`` problems (empty list: healthy)."""
    with open_db(Path(db_path), create=False, readonly=True) as db:
        return db.integrity_check()


def open_database(db_path: Path) -> Database:
    return open_db(Path(db_path), create=False, readonly=True)


def default_workers() -> int:
    return max(1, os.cpu_count() or 1)
