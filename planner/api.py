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

Heavy libraries (trimesh, PyBullet, scipy, h5py, pyarrow, the exporters) are
imported by the functions that use them, and the names re-exported from
their modules are loaded on first use (:data:`_LAZY`): importing the API, and
so starting the ``grasp`` command, costs numpy and the specs alone.
"""

from __future__ import annotations

import importlib
import itertools
import json
import logging
import math
import os
import shlex
import time
from collections import Counter
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import closing
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from planner.db.lock import writer_lock
from planner.db.ranking import RankingRule
from planner.db.store import Database, ObjectRow, UnitRow, open_db
from planner.errors import InputError, UnknownNameError
from planner.plan.sweep import SAMPLER_DEFAULTS, SweepSettings, candidate_count
from planner.plan.tolerances import PREGRASP_DISTANCE
from planner.record.grasp import Grasp
from planner.specs.hands import SAMPLERS, HandSpec, check_hand_name, hand_names, load_hand
from planner.specs.inputs import expand
from planner.specs.objects import (
    NO_PHYSICAL,
    RANDOM_COUNT,
    RANDOM_PREFIX,
    ObjectSpec,
    Physical,
    builtin_specs,
    is_registered,
    resolve_spec,
)
from planner.specs.preshapes import Preshape, load_preshapes, sweep_preshapes

if TYPE_CHECKING:
    from planner.calibration.fitting import Calibration
    from planner.calibration.model import LogisticModel
    from planner.datasets.exporter import FORMATS as EXPORT_FORMATS
    from planner.datasets.exporter import ExportSummary, export
    from planner.datasets.importer import FORMATS as IMPORT_FORMATS
    from planner.datasets.importer import ImportResult, import_files
    from planner.db.diverse import Spacing
    from planner.geometry.solid import PreparedObject
    from planner.geometry.stable import RestingPose
    from planner.geometry.support import Support
    from planner.plan.reach import ReachScene
    from planner.plan.unit import UnitResult, UnitSpec
    from planner.validation.run import ValidationSummary, validate

__all__ = [
    "DEFAULT_DB", "EXPORT_FORMATS", "IMPORT_FORMATS", "RANDOM_COUNT", "RANDOM_PREFIX", "ExportSummary", "Grasp",
    "GenerateProgress", "ImportResult", "RankingRule", "ReachableGrasp", "SAMPLERS", "SAMPLER_DEFAULTS", "Summary",
    "SweepSettings", "UnitResult", "ValidationSummary",
    "best", "best_at", "calibrate", "calibration_errors", "check_db", "default_workers", "export", "generate",
    "hand", "hands", "import_files", "objects", "plan_units", "report", "resolve_object", "show", "validate",
]

log = logging.getLogger(__name__)

DEFAULT_DB = Path("grasps.db")
#: Names of this module loaded from their modules on first use: name -> (module, attribute).
_LAZY = {
    "EXPORT_FORMATS": ("planner.datasets.exporter", "FORMATS"),
    "ExportSummary": ("planner.datasets.exporter", "ExportSummary"),
    "export": ("planner.datasets.exporter", "export"),
    "IMPORT_FORMATS": ("planner.datasets.importer", "FORMATS"),
    "ImportResult": ("planner.datasets.importer", "ImportResult"),
    "import_files": ("planner.datasets.importer", "import_files"),
    "UnitResult": ("planner.plan.unit", "UnitResult"),
    "UnitSpec": ("planner.plan.unit", "UnitSpec"),
    "run_unit": ("planner.plan.unit", "run_unit"),
    "ValidationSummary": ("planner.validation.run", "ValidationSummary"),
    "validate": ("planner.validation.run", "validate"),
}
#: ``best_at`` reads stored grasps in rank order this many at a time.
CANDIDATE_BATCH = 50
#: ``best_at`` tries at most this many top-ranked grasps by default.
MAX_CANDIDATES = 300
TABLE_AT = (0.5, 0.0)  # [m] where --on-table puts the object, robot base frame
DIVERSE_BATCH = 500  # grasps read at a time while picking diverse ones
#: [s] the pool stops a worker this long after ``--unit-timeout``: the unit
#: checks its own time between candidates and ends cleanly; the pool's kill is
#: for a simulator call that never returns.
UNIT_TIMEOUT_GRACE = 10.0
#: A typed quaternion whose norm lies outside this range is a mistake, not round-off.
QUATERNION_NORM = (0.5, 2.0)
#: Stored object names an "unknown object" error lists at most.
LISTED_NAMES = 12
#: Relative difference below which a stored mass, density or friction is the
#: one given: a density comes back from the store as mass / volume, a few ulp off.
PROPERTY_RTOL = 1e-9


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


@dataclass(frozen=True)
class GenerateProgress:
    """What ``generate`` tells its ``progress`` callback: after the plan
    (nothing run yet), as running units report candidates (``result`` None),
    and when a unit is written (``result`` its result).

    ``candidates_total``: the candidates of every unit to do, planned from the
    settings, a unit's own count once it reports (None while unknown: the box
    sampler before any unit began); ``candidates_done`` never goes down, and
    counts a finished unit (budget spent, failed) as its whole total and a
    retried one once (:class:`planner.run.progress.Tally`). On Ray it moves
    only as units finish."""

    units_done: int
    units_total: int
    candidates_done: int
    candidates_total: int | None
    result: UnitResult | None = None


def __getattr__(name: str) -> Any:
    """A name of :data:`_LAZY`, imported now and kept (so a test may patch it)."""
    if name not in _LAZY:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    module, attribute = _LAZY[name]
    value = getattr(importlib.import_module(module), attribute)
    globals()[name] = value
    return value


def _lazy(name: str) -> Any:
    return globals()[name] if name in globals() else __getattr__(name)


# -- building -----------------------------------------------------------------------
def plan_units(names: Sequence[str], hand: str, settings: SweepSettings, seed: int,
               scale: float | None = None, physical: Physical = NO_PHYSICAL, on_table: int = 0) -> list[UnitSpec]:
    """Expand the object arguments and check every input up front (names,
    hand, preshapes, physical properties) before any work. ``on_table`` > 0:
    each object's units plan on the table in each of its ``on_table`` most
    probable resting poses (:func:`table_supports`) instead of on the object
    alone."""
    from planner.geometry.solid import load_object

    unit_spec = _lazy("UnitSpec")
    refs = expand(list(names), scale, physical)
    if not refs:
        raise InputError("no objects given")
    if on_table < 0:
        raise InputError(f"--stable-poses must be at least 1, got {on_table}")
    hand_spec = load_hand(hand)
    settings = settings.resolved(hand_spec.sampler, hand_spec.settle)
    load_preshapes(hand_spec, list(settings.preshapes) if settings.preshapes else None)
    units, seen = [], {}
    for ref in refs:
        spec = resolve_spec(ref.source, scale=ref.scale, label=ref.label, **ref.physical.given())
        if spec.kind == "mesh" and not spec.source.startswith("pybullet_data:") and not Path(spec.source).exists():
            raise InputError(f"{spec.source}: file not found")
        if spec.name in seen:
            if seen[spec.name] != spec:
                raise InputError(f"object '{spec.name}' is given twice with different scale, mass, density or "
                                 "friction; give it once")
            continue
        seen[spec.name] = spec
        planned = [settings]
        if on_table:
            obj = load_object(ref.source, scale=ref.scale, label=spec.name, **ref.physical.given())
            planned = [settings.on(support) for support in table_supports(obj, on_table)]
        units += [unit_spec(ref.source, hand, plan, seed, ref.scale, chunk, label=spec.name, physical=ref.physical)
                  for plan in planned for chunk in range(plan.chunks())]
    if len(refs) == 1:
        # One object: a broken mesh is the user's input error, reported before
        # the database is opened. In a batch it is recorded and the rest go on.
        load_object(refs[0].source, scale=refs[0].scale, **refs[0].physical.given())
    return units


def table_supports(obj: PreparedObject, poses: int) -> list[Support]:
    """The table tops under the object in its ``poses`` most probable resting
    poses (:mod:`planner.geometry.stable`), most probable first."""
    from planner.geometry.stable import resting_poses
    from planner.geometry.support import Support

    return [Support.resting(r.pose) for r in resting_poses(obj.mesh, obj.com, poses)]


def _check_stored_physics(db: Database, units: Sequence[UnitSpec]) -> None:
    """Refuse to add grasps of an object at another mass, density or friction
    than its stored grasps were measured at: one name, one set of properties."""
    checked: set[str] = set()
    for unit in units:
        name = unit.label or unit.object_name
        row = db.object_row(name) if name not in checked else None
        checked.add(name)
        if row is None:
            continue
        spec = resolve_spec(unit.object_name, scale=unit.scale, label=unit.label, **unit.physical.given())
        stored = {"density": row.density} if spec.density is not None else {"mass": row.mass}
        given = {"density": spec.density} if spec.density is not None else {"mass": spec.mass}
        stored["friction"], given["friction"] = row.friction, spec.friction
        if any(not math.isclose(given[k], stored[k], rel_tol=PROPERTY_RTOL) for k in given):
            def text(values: dict[str, float]) -> str:
                return ", ".join(f"{k} {v:g}" for k, v in values.items())

            raise InputError(f"object '{name}' is stored in {db.path} with {text(stored)}, this run gives "
                             f"{text(given)}; its grasps were measured at the stored values: use another --db, or "
                             "name the object apart (copy the mesh under another name)")


def generate(names: Sequence[str], hand: str, *, db_path: Path = DEFAULT_DB, settings: SweepSettings | None = None,
             seed: int = 0, workers: int = 1, scale: float | None = None, rule: RankingRule | None = None,
             use_ray: bool = False, ray_address: str | None = None, unit_timeout: float | None = None,
             progress: Callable[[GenerateProgress], None] | None = None,
             mass: float | None = None, density: float | None = None, friction: float | None = None,
             on_table: int = 0) -> Summary:
    """Build (or extend) a grasp database; finished units are skipped, so a
    run that was killed resumes when called again. Units run in this process
    (``workers`` 1), in a crash-safe pool of ``workers`` processes, or on Ray
    (:func:`planner.run.pool.execute`); a unit whose worker dies twice, or
    that fails, is stored as failed with its error and the batch goes on.
    ``mass`` [kg] or ``density`` [kg/m^3], and ``friction``, apply to every
    object except where a manifest line gives its own (see
    :mod:`planner.specs.objects`); an object stored at other values is refused.
    ``on_table`` > 0: plan on the table in each object's ``on_table`` most
    probable resting poses (the grasps keep the hand off the table and record
    its plane, ``table_plane``), not on the object alone.
    ``progress(GenerateProgress)`` once the work is planned, then as it goes."""
    from planner.run import pool
    from planner.run.progress import Tally

    if workers < 1:
        raise InputError(f"--workers must be at least 1, got {workers}")
    physical = Physical.checked({"mass": mass, "density": density, "friction": friction}, prefix="--")
    hand_spec = load_hand(hand)
    settings = (settings or SweepSettings()).resolved(hand_spec.sampler, hand_spec.settle)
    units = plan_units(names, hand, settings, seed, scale, physical, on_table)
    summary = Summary()
    start = time.perf_counter()
    with writer_lock(Path(db_path)), open_db(Path(db_path)) as db:
        _check_stored_physics(db, units)
        rule = rule or db.rule()
        db.apply_rule(rule)
        done = {d: db.units_done(hand, d, seed) for d in sorted({u.settings.digest for u in units})}
        todo = [u for u in units if (u.label, u.chunk) not in done[u.settings.digest]]
        summary.skipped = len(units) - len(todo)
        names = list(settings.preshapes) if settings.preshapes else None
        tally = Tally([candidate_count(u.settings, sweep_preshapes(hand_spec, names, u.settings.support() is not None),
                                       u.chunk) for u in todo])
        finished = 0

        def tell(result: UnitResult | None = None) -> None:
            if progress:
                progress(GenerateProgress(finished, len(todo), tally.done, tally.total, result))

        def reported(index: int, done: int, total: int) -> None:
            tally.report(index, done, total)
            tell()

        tell()
        if unit_timeout:
            todo = [replace(u, timeout=unit_timeout) for u in todo]
        hard_timeout = unit_timeout + UNIT_TIMEOUT_GRACE if unit_timeout else None
        ray = (ray_address or "local") if use_ray else None
        unit_result = _lazy("UnitResult")
        index = {_unit_key(u): i for i, u in enumerate(todo)}
        with closing(pool.execute(_lazy("run_unit"), todo, workers, timeout=hard_timeout, ray=ray,
                                  progress=reported if progress else None)) as outcomes:
            for unit, outcome, seconds in outcomes:
                result = outcome if isinstance(outcome, unit_result) else unit_result(unit, error=str(outcome))
                db.write_unit(unit_row(result, seconds), result.obj, result.grasps, rule)
                _tally(summary, result, seconds)
                finished += 1
                tally.finish(index[_unit_key(unit)])
                tell(result)
    summary.seconds = time.perf_counter() - start
    return summary


def _unit_key(unit: UnitSpec) -> tuple[str | None, str, int]:
    """What tells a run's units apart: object, settings (the table plane among them), chunk."""
    return unit.label, unit.settings.digest, unit.chunk


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
    planned with: :func:`~planner.db.objects.stored_object` rebuilds it.
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
    from planner.db.objects import stored_object

    key, row = resolve_object(db, name)
    if row is None:
        raise InputError(f"no grasps of '{key}' for hand '{hand}' in {db.path}; "
                         f"run `{generate_command(name, row, hand, db.path)}`")
    return key, stored_object(row)


def generate_command(name: str, row: ObjectRow | None, hand: str, db_path: Path) -> str:
    """The ``grasp generate`` command that plans the object ``name`` means
    for ``hand``: a stored mesh by its file (its name alone is no object),
    with the stored scale, mass and friction where the file does not give them."""
    db = "" if Path(db_path) == DEFAULT_DB else f" --db {shlex.quote(str(db_path))}"
    if row is None or is_registered(row.name) or not Path(row.source).is_file():
        return f"grasp generate {shlex.quote(name)} --hand {hand}{db}"
    scale = None if row.scale == 1.0 else row.scale
    own = resolve_spec(row.source, scale=scale)
    extra = "" if scale is None else f" --scale {scale!r}"
    if not math.isclose(own.mass, row.mass, rel_tol=PROPERTY_RTOL) and own.density is None:
        extra += f" --mass {row.mass!r}"
    if own.density is not None and not math.isclose(own.density, row.density, rel_tol=PROPERTY_RTOL):
        extra += f" --density {row.density!r}"
    if not math.isclose(own.friction, row.friction, rel_tol=PROPERTY_RTOL):
        extra += f" --friction {row.friction!r}"
    return f"grasp generate {shlex.quote(row.source)} --hand {hand}{extra}{db}"


def best(name: str, hand: str, *, db_path: Path = DEFAULT_DB, top: int = 1, spacing: Spacing | None = None
         ) -> list[Grasp]:
    """The ``top`` best grasps of an object for a hand, in rank order; with
    ``spacing``, the best ``top`` that are each that far from every better
    one kept (:mod:`planner.db.diverse`)."""
    if top < 1:
        raise InputError(f"--top must be at least 1, got {top}")
    check_hand_name(hand)
    with open_db(Path(db_path), create=False, readonly=True) as db:
        key, row = resolve_object(db, name)
        if spacing is None:
            grasps = db.best(key, hand, top)
        else:
            from planner.db.diverse import diverse

            spec = load_hand(hand)
            with closing(db.grasp_batches(key, hand, size=DIVERSE_BATCH)) as batches:  # its cursor, before the db
                ranked = (g for batch in batches for g in batch if g.rank)
                grasps = diverse(ranked, top, spacing, spec.tcp, spec.approach, spec.roll_symmetry)
        if not grasps:
            known = db.objects_for(hand)
            raise InputError(f"no grasps of '{key}' for hand '{hand}' in {db_path}; objects with grasps: "
                             f"{', '.join(known) or '(none)'}; run `{generate_command(name, row, hand, db_path)}`")
    return grasps


def ranking_rule(db_path: Path = DEFAULT_DB) -> RankingRule:
    """The ranking rule a database's scores were made with (``meta.ranking``)."""
    with open_db(Path(db_path), create=False, readonly=True) as db:
        return db.rule()


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


def p_hold_model(hand: str, *, db_path: Path = DEFAULT_DB) -> LogisticModel | None:
    """The p_hold model a database applies to ``hand``'s grasps (stored by
    ``grasp calibrate``, else the shipped one; None: none)."""
    with open_db(Path(db_path), create=False, readonly=True) as db:
        return db.model(hand)


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
    ``top`` of them are force closure and ``plan``, grasps are also planned
    on the spot with the table under the object (:func:`_plan_now`, from
    ``seed``), and the force-closure ones come first (:func:`_preferred`). ``misses``, if
    given, receives (rank, why) of each one tried and not reachable (rank 0:
    planned on the spot)."""
    from planner.plan.reach import ReachScene, ReachSettings
    from planner.sim import Sim

    if top < 1 or max_candidates < 0:
        raise InputError(f"--top must be at least 1 and --max-candidates at least 0, got {top} and {max_candidates}")
    obj_pose = _pose7(object_pose, "--object-pose")
    base = _pose7(robot_base, "--robot-base") if robot_base is not None else np.eye(4)
    spec = load_hand(hand)
    missed = misses if misses is not None else []
    with open_db(Path(db_path), create=False, readonly=True) as db, db.snapshot(), Sim() as sim:
        key, obj = _stored(db, name, hand)
        scene = ReachScene(sim, spec, obj, ReachSettings(pregrasp_distance=pregrasp_distance), base)
        rng = np.random.default_rng(seed)
        found = _reachable(db, scene, key, hand, obj_pose, top, max_candidates, rng, missed)
        if plan and _closures(found) < top:
            found = _preferred(found, _plan_now(db, scene, obj, obj_pose, top, seed, rng, missed), top)
        return found


def _closures(found: Sequence[ReachableGrasp]) -> int:
    return sum(bool(r.grasp.force_closure) for r in found)


def _preferred(stored: list[ReachableGrasp], planned: list[ReachableGrasp], top: int) -> list[ReachableGrasp]:
    """The ``top`` to return of reachable stored grasps (rank order) and grasps
    planned on the spot (best first): force closure first, stored before
    planned."""
    return sorted([*stored, *planned], key=lambda r: not r.grasp.force_closure)[:top]  # stable: keeps each order


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
                         **PLAN_NOW[hand.sampler]).resolved(hand.sampler, hand.settle)


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
        """x, y, z, qx, qy, qz, qw, as ``--object-pose`` takes it."""
        from scipy.spatial.transform import Rotation

        return [*self.object_pose[:3, 3].tolist(), *Rotation.from_matrix(self.object_pose[:3, :3]).as_quat().tolist()]

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
        key, obj = _stored(db, name, hand)
        scene = ReachScene(sim, spec, obj, ReachSettings(table_height=table_height), base)
        rng = np.random.default_rng(seed)
        for resting in resting_poses(obj.mesh, obj.com, poses):
            pose = resting.placed(xy[0], xy[1], table_height)
            misses: list[tuple[int, str]] = []
            found = _reachable(db, scene, key, hand, pose, top, max_candidates, rng, misses)
            if plan and _closures(found) < top:
                found = _preferred(found, _plan_now(db, scene, obj, pose, top, seed, rng, misses), top)
            out.append(TableGrasps(resting, pose, found, misses))
    return out


def object_pose_matrix(values: Sequence[float]) -> np.ndarray:
    """(4, 4) the pose ``--object-pose`` x,y,z,qx,qy,qz,qw gives (checked)."""
    return _pose7(values, "--object-pose")


def _pose7(values: Sequence[float], option: str) -> np.ndarray:
    from planner.geometry.frames import pose_from_xyzquat

    vals = [float(v) for v in values]
    if len(vals) != 7 or not all(np.isfinite(vals)):
        raise InputError(f"{option} needs 7 finite numbers x,y,z,qx,qy,qz,qw; got {values}")
    q = np.array(vals[3:])
    lo, hi = QUATERNION_NORM
    if not lo < np.linalg.norm(q) < hi:
        raise InputError(f"{option}: quaternion {vals[3:]} is not close to unit length")
    vals[3:] = list(q / np.linalg.norm(q))
    return pose_from_xyzquat(vals)


def show(name: str, hand: str, out: Path, *, db_path: Path = DEFAULT_DB, rank: int = 1, top: int | None = None,
         spacing: Spacing | None = None) -> list[Grasp]:
    """Render grasp ``rank`` (or the ``top`` K as a contact sheet; with
    ``spacing``, the K best diverse ones) to a PNG."""
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
        grasps = db.best(key, hand, count, first - 1) if spacing is None else \
            best(key, hand, db_path=db_path, top=first - 1 + count, spacing=spacing)[first - 1:]
    if not grasps:
        raise InputError(f"no grasp of rank {first} for '{key}' and hand '{hand}' in {db_path}")
    render.save_sheet([(render.grasp_views(spec, obj, g), render.title(g)) for g in grasps], Path(out))
    return grasps


def view(name: str, hands: Sequence[str] | None = None, *, db_path: Path = DEFAULT_DB, top: int = 50,
         host: str = "127.0.0.1", port: int = 8080, object_pose: Sequence[float] | None = None,
         robot_base: Sequence[float] | None = None, spacing: Spacing | None = None):  # -> viewer.Viewer
    """Start the browser viewer on the ``top`` best grasps of each hand (all
    hands with grasps of the object when ``hands`` is None). With
    ``object_pose`` only grasps the arm reaches at that pose are offered,
    placed in the world with the arm (stored ones; if none is reachable,
    grasps planned on the spot with the table, as ``best --object-pose``). Returns the running viewer (``url``,
    ``stop()``)."""
    from planner.db.objects import stored_object
    from planner.present import scene as scenes
    from planner.present import viewer

    if top < 1:
        raise InputError(f"--top must be at least 1, got {top}")
    with open_db(Path(db_path), create=False, readonly=True) as db:
        key, row = resolve_object(db, name)
        stored = sorted(h for o, h in db.pairs() if o == key)
        if row is None or not stored:
            raise InputError(f"no grasps of '{key}' in {db_path}; run `grasp generate {name} --hand panda`")
        obj = stored_object(row)
    chosen = list(hands) if hands else stored
    missing = [h for h in chosen if h not in stored]
    if missing:
        raise InputError(f"no grasps of '{key}' for hand(s) {', '.join(missing)} in {db_path} "
                         f"(hands with grasps: {', '.join(stored)})")
    specs = {h: load_hand(h) for h in chosen}
    world = None if object_pose is None else _pose7(object_pose, "--object-pose")
    base = None if robot_base is None else _pose7(robot_base, "--robot-base")
    entries: list[viewer.Entry] = []
    for h in chosen:
        if object_pose is None:
            found = [(g, None, ()) for g in best(key, h, db_path=db_path, top=top, spacing=spacing)]
        else:
            reached = best_at(key, h, object_pose, db_path=db_path, top=top, robot_base=robot_base, plan=False) or \
                best_at(key, h, object_pose, db_path=db_path, top=top, robot_base=robot_base, max_candidates=0)
            found = [(r.grasp, r.arm_grasp, (_arm_line(r),)) for r in reached]
        for g, arm, extra in found:
            def build(g=g, arm=arm, spec=specs[h]):  # noqa: B023 - bound per grasp
                return scenes.grasp_scene(spec, obj.mesh, g, obj.friction, world, arm, base)
            entries.append(viewer.Entry(g, build, extra))
    if not entries:
        raise InputError(f"no grasp of '{key}' is reachable at --object-pose {object_pose}, stored or planned on "
                         "the spot with the table; `grasp best ... --object-pose ...` says why")
    return viewer.Viewer(entries, specs, scenes.object_part(obj.mesh, world), host=host, port=port)


def coverage(db_path: Path, top: int = 10):  # -> list[planner.present.coverage.Coverage]
    """Surface coverage of the ``top`` best (and diverse) grasps' contacts, per object and hand."""
    from planner.present.coverage import coverages

    return coverages(Path(db_path), top)


def _arm_line(r: ReachableGrasp) -> str:
    joints = ", ".join(f"{k} {v:.3f}" for k, v in r.arm_grasp.items())
    return f"arm joints at the grasp [rad]: {joints}"


def report(db_path: Path, out: Path) -> Path:
    """The calibration report of ``db_path``: ``out.html``, or a folder with
    ``report.md`` and PNGs (the reliability diagram of each hand's p_hold
    among them); returns the file written."""
    from planner.present import report as reporting

    return reporting.write(Path(db_path), Path(out))


def calibration_errors(db_path: Path) -> list[str]:
    """Per hand with a p_hold model: the expected calibration error of each of
    its reliability tables (held out on its labels; against stored trials)."""
    from planner.present import report as reporting

    return reporting.ece_lines(reporting.calibration(Path(db_path)))


# -- calibrating ---------------------------------------------------------------------
def calibrate(label_files: Sequence[Path], *, db_path: Path | None = DEFAULT_DB, poses: int | None = 200, seed: int = 0,
              folds: int = 5, hand: str | None = None, workers: int = 1, model_out: Path | None = None,
              plot: Path | None = None, progress: Callable[[Path, int, int], None] | None = None
              ) -> Calibration:
    """Fit p_hold (and so the ranking, by p_hold) to labelled grasp files in
    ACRONYM layout: a seeded sample of ``poses`` poses per file re-scored as
    ``import --rescore`` does, cross-validated over ``folds`` folds grouped by
    object. The model and its source are stored in ``db_path`` (None: not
    stored), where ``best``, exports and reports use it for its hand;
    ``model_out`` writes it as TOML (the form of the shipped default),
    ``plot`` the held-out reliability diagram as PNG."""
    from planner.calibration.fitting import calibrate as fit_calibration
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
    result = fit_calibration(data, folds=folds, source=source)
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
