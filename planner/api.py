"""The Python API, the one facade of the project: the ``grasp`` CLI only
wraps these functions (and the names re-exported here).

- building: :func:`generate` (sweep objects for a hand into a database);
- querying: :func:`best`, :func:`best_at` (grasps an arm reaches now), :func:`show`,
  each naming the object as :func:`resolve_object` reads it;
- validating: :func:`validate`, :func:`report`;
- calibrating: :func:`calibrate` (p_hold fitted to labelled grasp files);
- datasets: :func:`export`, :func:`import_files`;
- descriptions: :func:`hands`, :func:`hand`, :func:`objects`;
- maintenance: :func:`check_db`.
"""

from __future__ import annotations

import json
import logging
import os
import time
from collections import Counter
from collections.abc import Callable, Sequence
from contextlib import closing
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from planner.calibration import fitting as calibration
from planner.datasets import exporter, importer
from planner.datasets.exporter import ExportSummary, export
from planner.datasets.importer import ImportResult, import_files
from planner.datasets.meshes import stored_object
from planner.db.lock import writer_lock
from planner.db.ranking import RankingRule
from planner.db.store import Database, ObjectRow, UnitRow, open_db
from planner.errors import InputError, UnknownNameError
from planner.geometry.frames import pose_from_xyzquat
from planner.geometry.solid import PreparedObject, load_object
from planner.grasp import Grasp
from planner.plan import pool
from planner.plan.reach import ReachScene, ReachSettings
from planner.plan.sampling import SAMPLERS
from planner.plan.sweep import SAMPLER_DEFAULTS, SweepSettings
from planner.plan.tolerances import PREGRASP_DISTANCE
from planner.plan.unit import UnitResult, UnitSpec, run_unit
from planner.present import report as reporting
from planner.sim import Sim
from planner.specs.hands import HandSpec, hand_names, load_hand
from planner.specs.inputs import expand
from planner.specs.objects import RANDOM_COUNT, RANDOM_PREFIX, ObjectSpec, builtin_specs, resolve_spec
from planner.specs.preshapes import Preshape, load_preshapes
from planner.validation.run import ValidationSummary, validate

__all__ = [
    "DEFAULT_DB", "EXPORT_FORMATS", "IMPORT_FORMATS", "RANDOM_COUNT", "RANDOM_PREFIX", "ExportSummary", "Grasp",
    "ImportResult", "RankingRule", "ReachableGrasp", "SAMPLERS", "SAMPLER_DEFAULTS", "Summary", "SweepSettings",
    "UnitResult", "ValidationSummary",
    "best", "best_at", "calibrate", "calibration_errors", "check_db", "default_workers", "export", "generate",
    "hand", "hands", "import_files", "objects", "plan_units", "report", "resolve_object", "show", "validate",
]

log = logging.getLogger(__name__)

DEFAULT_DB = Path("grasps.db")
EXPORT_FORMATS = exporter.FORMATS
IMPORT_FORMATS = importer.FORMATS
#: ``best_at`` reads stored grasps in rank order this many at a time.
CANDIDATE_BATCH = 50
#: ``best_at`` tries at most this many top-ranked grasps by default.
MAX_CANDIDATES = 300
#: [s] the pool stops a worker this long after ``--unit-timeout``: the unit
#: checks its own time between candidates and ends cleanly; the pool's kill is
#: for a simulator call that never returns.
UNIT_TIMEOUT_GRACE = 10.0
#: A typed quaternion whose norm lies outside this range is a mistake, not round-off.
QUATERNION_NORM = (0.5, 2.0)
#: Stored object names an "unknown object" error lists at most.
LISTED_NAMES = 12


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


# -- building -----------------------------------------------------------------------
def plan_units(names: Sequence[str], hand: str, settings: SweepSettings, seed: int,
               scale: float | None = None) -> list[UnitSpec]:
    """Expand the object arguments and check every input up front (names,
    hand, preshapes) before any work."""
    refs = expand(list(names), scale)
    if not refs:
        raise InputError("no objects given")
    hand_spec = load_hand(hand)
    settings = settings.resolved(hand_spec.sampler, hand_spec.settle)
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
             progress: Callable[[UnitResult | None, int, int], None] | None = None) -> Summary:
    """Build (or extend) a grasp database; finished units are skipped, so a
    run that was killed resumes when called again. Units run in this process
    (``workers`` 1), in a crash-safe pool of ``workers`` processes, or on Ray
    (:func:`planner.plan.pool.execute`); a unit whose worker dies twice, or
    that fails, is stored as failed with its error and the batch goes on.
    ``progress(None, 0, total)`` first, then ``progress(result, done, total)``."""
    hand_spec = load_hand(hand)
    settings = (settings or SweepSettings()).resolved(hand_spec.sampler, hand_spec.settle)
    units = plan_units(names, hand, settings, seed, scale)
    summary = Summary()
    start = time.perf_counter()
    with writer_lock(Path(db_path)), open_db(Path(db_path)) as db:
        rule = rule or db.rule()
        db.apply_rule(rule)
        done = db.units_done(hand, settings.digest, seed)
        todo = [u for u in units if (u.label, u.chunk) not in done]
        summary.skipped = len(units) - len(todo)
        if progress:
            progress(None, 0, len(todo))
        if unit_timeout:
            todo = [replace(u, timeout=unit_timeout) for u in todo]
        hard_timeout = unit_timeout + UNIT_TIMEOUT_GRACE if unit_timeout else None
        ray = (ray_address or "local") if use_ray else None
        with closing(pool.execute(run_unit, todo, workers, timeout=hard_timeout, ray=ray)) as outcomes:
            for done_count, (unit, outcome, seconds) in enumerate(outcomes, start=1):
                result = outcome if isinstance(outcome, UnitResult) else UnitResult(unit, error=str(outcome))
                db.write_unit(unit_row(result, seconds), result.obj, result.grasps, rule)
                _tally(summary, result, seconds)
                if progress:
                    progress(result, done_count, len(todo))
    summary.seconds = time.perf_counter() - start
    return summary


def unit_row(result: UnitResult, seconds: float) -> UnitRow:
    """The ``units`` row of a finished (or failed) unit."""
    spec = result.spec
    return UnitRow(result.object_name, spec.hand, spec.settings.digest, spec.settings.to_json(), spec.seed,
                   spec.chunk, result.error, result.candidates, dict(result.rejected), seconds)


def _tally(summary: Summary, result: UnitResult, seconds: float) -> None:
    summary.units += 1
    name = result.object_name
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


# -- querying -----------------------------------------------------------------------
def resolve_object(db: Database, name: str) -> tuple[str, ObjectRow | None]:
    """The database's name and ``objects`` row of the object ``name`` means.

    ``name`` is a stored object's name (any object with grasps: built-in,
    ``random_NNN``, a user mesh by its stem or label, an imported object, a
    mesh generated with ``--scale``), else a built-in name, ``random_NNN`` or
    mesh path, named as ``generate`` names it. The row (None when the object
    is not stored) holds the source, scale, mass and friction its grasps were
    planned with: :func:`~planner.datasets.meshes.stored_object` rebuilds it.
    """
    row = db.object_row(name)
    if row is not None:
        return name, row
    try:
        key = resolve_spec(name).name
    except UnknownNameError:
        stored = sorted({o for o, _ in db.pairs()})
        listed = ", ".join(stored[:LISTED_NAMES]) + (f", ... ({len(stored)} in all)" if len(stored) > LISTED_NAMES
                                                     else "")
        raise InputError(f"unknown object '{name}': not stored in {db.path} (objects: {listed or 'none'}) and not "
                         f"a built-in name, random_NNN or mesh file (see `grasp objects`)") from None
    return key, db.object_row(key)


def _stored(db: Database, name: str, hand: str) -> tuple[str, PreparedObject]:
    """Name and rebuilt object of a stored object; an object without grasps is an error."""
    key, row = resolve_object(db, name)
    if row is None:
        raise InputError(f"no grasps of '{key}' for hand '{hand}' in {db.path}; "
                         f"run `grasp generate {name} --hand {hand}`")
    return key, stored_object(row)


def best(name: str, hand: str, *, db_path: Path = DEFAULT_DB, top: int = 1) -> list[Grasp]:
    """The ``top`` best grasps of an object for a hand, in rank order."""
    if top < 1:
        raise InputError(f"--top must be at least 1, got {top}")
    load_hand(hand)
    with open_db(Path(db_path), create=False, readonly=True) as db:
        key, _ = resolve_object(db, name)
        grasps = db.best(key, hand, top)
        if not grasps:
            known = db.objects_for(hand)
            raise InputError(f"no grasps of '{key}' for hand '{hand}' in {db_path}; objects with grasps: "
                             f"{', '.join(known) or '(none)'}; run `grasp generate {name} --hand {hand}`")
    return grasps


@dataclass(frozen=True)
class ReachableGrasp:
    """A stored grasp with the arm solutions that reach it at a given pose."""

    grasp: Grasp
    arm_grasp: dict[str, float]  # arm joint values [rad] at the grasp
    arm_pregrasp: dict[str, float]  # ... and at the pre-grasp
    manipulability: float
    hand_pose_world: list[list[float]]  # (4, 4) where the hand frame ends up [m]

    def to_json(self) -> dict:
        return {**self.grasp.to_json(), "arm": {"grasp": self.arm_grasp, "pregrasp": self.arm_pregrasp},
                "arm_manipulability": self.manipulability, "hand_pose_world": self.hand_pose_world}


def best_at(name: str, hand: str, object_pose: Sequence[float], *, db_path: Path = DEFAULT_DB, top: int = 1,
            robot_base: Sequence[float] | None = None, max_candidates: int = MAX_CANDIDATES,
            pregrasp_distance: float = PREGRASP_DISTANCE, seed: int = 0) -> list[ReachableGrasp]:
    """The best stored grasps that an arm reaches *now*, with the object at
    ``object_pose`` (x, y, z, qx, qy, qz, qw, world frame) and the robot base at
    ``robot_base`` (same form; default the origin). Candidates are tried in
    rank order, at most ``max_candidates`` of them."""
    if top < 1:
        raise InputError(f"--top must be at least 1, got {top}")
    obj_pose = _pose7(object_pose, "--object-pose")
    base = _pose7(robot_base, "--robot-base") if robot_base is not None else np.eye(4)
    spec = load_hand(hand)
    rng = np.random.default_rng(seed)
    found: list[ReachableGrasp] = []
    with open_db(Path(db_path), create=False, readonly=True) as db, db.snapshot(), Sim() as sim:
        key, obj = _stored(db, name, hand)
        scene = ReachScene(sim, spec, obj, ReachSettings(pregrasp_distance=pregrasp_distance), base)
        scene.place_object(obj_pose)
        offset = 0
        while len(found) < top and offset < max_candidates:
            batch = db.best(key, hand, min(CANDIDATE_BATCH, max_candidates - offset), offset)
            if not batch:
                break
            offset += len(batch)
            for g in batch:
                if not g.score:
                    continue
                reach = scene.check(g.pose, g.closed_joints, g.open_joints, rng)
                if reach.grasp is not None and reach.pregrasp is not None:
                    found.append(ReachableGrasp(g, reach.grasp.joints, reach.pregrasp.joints,
                                                reach.grasp.manipulability, (obj_pose @ g.pose).tolist()))
                    if len(found) == top:
                        break
        if offset == 0:
            raise InputError(f"no grasps of '{key}' for hand '{hand}' in {db_path}; "
                             f"run `grasp generate {name} --hand {hand}`")
    return found


def _pose7(values: Sequence[float], option: str) -> np.ndarray:
    vals = [float(v) for v in values]
    if len(vals) != 7 or not all(np.isfinite(vals)):
        raise InputError(f"{option} needs 7 finite numbers x,y,z,qx,qy,qz,qw; got {values}")
    q = np.array(vals[3:])
    lo, hi = QUATERNION_NORM
    if not lo < np.linalg.norm(q) < hi:
        raise InputError(f"{option}: quaternion {vals[3:]} is not close to unit length")
    vals[3:] = list(q / np.linalg.norm(q))
    return pose_from_xyzquat(vals)


def show(name: str, hand: str, out: Path, *, db_path: Path = DEFAULT_DB, rank: int = 1, top: int | None = None
         ) -> list[Grasp]:
    """Render grasp ``rank`` (or the ``top`` K as a contact sheet) to a PNG."""
    from planner.present import render  # matplotlib: only for pictures

    count = top or 1
    first = 1 if top else rank
    if count < 1 or first < 1:
        raise InputError("--rank and --top must be at least 1")
    spec = load_hand(hand)
    if Path(out).suffix.lower() != ".png":
        raise InputError(f"{out}: the picture is written as PNG; give a .png path")
    with open_db(Path(db_path), create=False, readonly=True) as db:
        key, obj = _stored(db, name, hand)
        grasps = db.best(key, hand, count, first - 1)
    if not grasps:
        raise InputError(f"no grasp of rank {first} for '{key}' and hand '{hand}' in {db_path}")
    render.save_sheet([(render.grasp_views(spec, obj, g), render.title(g)) for g in grasps], Path(out))
    return grasps


def report(db_path: Path, out: Path) -> Path:
    """The calibration report of ``db_path``: ``out.html``, or a folder with
    ``report.md`` and PNGs (the reliability diagram of each hand's p_hold
    among them); returns the file written."""
    return reporting.write(Path(db_path), Path(out))


def calibration_errors(db_path: Path) -> list[str]:
    """Per hand with a p_hold model: the expected calibration error of each of
    its reliability tables (held out on its labels; against stored trials)."""
    return reporting.ece_lines(reporting.calibration(Path(db_path)))


# -- calibrating ---------------------------------------------------------------------
def calibrate(label_files: Sequence[Path], *, db_path: Path | None = DEFAULT_DB, poses: int | None = 200, seed: int = 0,
              folds: int = 5, hand: str | None = None, workers: int = 1, model_out: Path | None = None,
              plot: Path | None = None, progress: Callable[[Path, int, int], None] | None = None
              ) -> calibration.Calibration:
    """Fit p_hold (and so the ranking, by p_hold) to labelled grasp files in
    ACRONYM layout: a seeded sample of ``poses`` poses per file re-scored as
    ``import --rescore`` does, cross-validated over ``folds`` folds grouped by
    object. The model and its source are stored in ``db_path`` (None: not
    stored), where ``best``, exports and reports use it for its hand;
    ``model_out`` writes it as TOML (the form of the shipped default),
    ``plot`` the held-out reliability diagram as PNG."""
    from planner.calibration.labels import labelled

    if plot is not None and Path(plot).suffix.lower() != ".png":
        raise InputError(f"{plot}: the reliability diagram is written as PNG; give a .png path")
    if folds < 2:
        raise InputError(f"--folds must be at least 2, got {folds}")
    paths = [Path(p) for p in label_files]
    data = labelled(paths, poses=poses, seed=seed, hand=hand, workers=workers, progress=progress)
    source = json.dumps({"command": "grasp calibrate", "labels": [p.name for p in paths], "poses_per_file": poses,
                         "seed": seed, "folds": folds, "grasps": len(data.labels), "objects": len(set(data.groups)),
                         "rejected": data.rejected}, sort_keys=True)
    result = calibration.calibrate(data, folds=folds, source=source)
    if db_path is not None:
        with writer_lock(Path(db_path)), open_db(Path(db_path)) as db:
            db.write_model(result.model, source, db.rule())
    if model_out is not None:
        Path(model_out).write_text(result.model.to_toml(), encoding="utf-8")
    if plot is not None:
        from planner.calibration.plot import reliability_png

        Path(plot).write_bytes(reliability_png([("held out (grouped CV)", result.reliability)],
                                               f"p_hold, {result.model.hand}: {len(data.labels)} labelled grasps"))
    return result


# -- descriptions and maintenance ------------------------------------------------------
def hands() -> list[tuple[HandSpec, tuple[Preshape, ...]]]:
    """Every built-in hand with its preshapes."""
    return [hand(name) for name in hand_names()]


def hand(name: str) -> tuple[HandSpec, tuple[Preshape, ...]]:
    """One hand and its preshapes."""
    spec = load_hand(name)
    return spec, load_preshapes(spec)


def objects() -> dict[str, ObjectSpec]:
    """The built-in objects by name (``random_NNN`` are not listed)."""
    return builtin_specs()


def check_db(db_path: Path) -> list[str]:
    """``PRAGMA integrity_check`` problems (empty list: healthy)."""
    with open_db(Path(db_path), create=False, readonly=True) as db:
        return db.integrity_check()


def default_workers() -> int:
    return max(1, os.cpu_count() or 1)
