"""Building a grasp database: :func:`generate` plans the units of work (:func:`plan_units`; on the table in the
object's resting poses, :func:`table_supports`), runs them (in this process, a process pool or Ray) and stores
each finished unit (:func:`unit_row`), reporting :class:`GenerateProgress` and returning a :class:`Summary`.

``UnitSpec``, ``UnitResult`` and ``run_unit`` (PyBullet's world) are read
from the facade :mod:`planner.api`, where they load on first use and where a
test may patch them (:func:`_lazy`).
"""

from __future__ import annotations

import importlib
import math
import sys
import time
from collections import Counter
from collections.abc import Callable, Iterator, Sequence
from contextlib import closing, contextmanager
from dataclasses import dataclass, field
from dataclasses import replace as replaced
from pathlib import Path
from typing import TYPE_CHECKING, Any

from planner import prepare
from planner.api.givers import from_files, note_overridden
from planner.api.resolving import DEFAULT_DB, PROPERTY_RTOL
from planner.api.sweeps import Replacement
from planner.db.hand_files import check_hand_files
from planner.db.ranking import RankingRule
from planner.db.store import Database, UnitRow, open_for_writing
from planner.errors import InputError
from planner.plan.sweep import SweepSettings, candidate_count, check_sampler, check_unit_size
from planner.specs.hands import load_hand
from planner.specs.inputs import check_seed, expand
from planner.specs.objects import resolve_spec
from planner.specs.physical import NO_PHYSICAL, Physical, density_note
from planner.specs.preshapes import load_preshapes, sweep_preshapes

if TYPE_CHECKING:
    from planner.geometry.solid import PreparedObject
    from planner.geometry.support import Support
    from planner.plan.unit import UnitResult, UnitSpec


#: [s] the pool stops a worker this long after ``--unit-timeout``: the unit
#: checks its own time between candidates and ends cleanly; the pool's kill is
#: for a simulator call that never returns.
UNIT_TIMEOUT_GRACE = 10.0
#: [s] the longest --unit-timeout: a unit of work is seconds to minutes; 1e300 overflowed the pool's wait.
MAX_UNIT_TIMEOUT = 7 * 24 * 3600.0


@dataclass
class Summary:
    """What a ``generate`` run did."""

    units: int = 0
    skipped: int = 0
    failed: dict[str, str] = field(default_factory=dict)
    candidates: int = 0
    grasps: int = 0
    force_closure: int = 0
    ends: int = 0  # of force_closure, the squeezes' ends kept as grasps of their own (planner.plan.keeping)
    rejected: Counter = field(default_factory=Counter)
    seconds: float = 0.0
    per_object: list[dict] = field(default_factory=list)
    replaced: int = 0  # grasps of earlier sweeps removed by ``replace``
    #: Objects every unit of which an earlier run finished: not in ``per_object``, which holds this run's work.
    finished_before: list[str] = field(default_factory=list)

    def to_json(self) -> dict:
        return {"units": self.units, "skipped": self.skipped, "finished_before": self.finished_before,
                "failed": self.failed, "candidates": self.candidates, "grasps": self.grasps,
                "force_closure": self.force_closure, "ends": self.ends, "rejected": dict(self.rejected),
                "seconds": round(self.seconds, 3), "objects": self.per_object, "replaced": self.replaced}


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


def _lazy(name: str) -> Any:
    """A name of the facade's :data:`planner.api._LAZY`, read from the facade
    (imported on first use there, and patched there by tests)."""
    return getattr(importlib.import_module("planner.api"), name)


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
    settings = settings.resolved(hand_spec.sampler, hand_spec.settle, hand_spec.settle_dynamics)
    check_sampler(settings, hand_spec)
    load_preshapes(hand_spec, list(settings.preshapes) if settings.preshapes else None)
    units, seen, box_rays = [], {}, None
    for ref in refs:
        spec = resolve_spec(ref.source, scale=ref.scale, label=ref.label, **ref.physical.given())
        if spec.kind == "mesh" and not spec.source.startswith("pybullet_data:") and not Path(spec.source).exists():
            raise InputError(f"{spec.source}: file not found")
        if spec.name in seen:
            if seen[spec.name] != spec:
                raise InputError(f"object '{spec.name}' is given twice with different scale, mass, density, "
                                 "friction or up; give it once")
            continue
        seen[spec.name] = spec
        note_overridden(ref.source, spec, ref.physical)
        planned = [settings]
        if on_table:
            obj = load_object(ref.source, scale=ref.scale, label=spec.name, **ref.physical.given())
            planned = [settings.on(support) for support in table_supports(obj, on_table)]
        units += [unit_spec(ref.source, hand, plan, seed, ref.scale, chunk, label=spec.name, physical=ref.physical,
                           manifest=ref.manifest)
                  for plan in planned for chunk in range(plan.chunks())]
    if len(refs) == 1:
        # One object: a broken mesh (or a box-sampler grid too fine for it) is
        # the user's input error, reported before the database is opened. In a
        # batch it is recorded and the rest go on.
        obj = load_object(refs[0].source, scale=refs[0].scale, **refs[0].physical.given())
        if settings.sampler == "box":
            from planner.plan.sampling import box_ray_count

            box_rays = box_ray_count(obj.mesh, settings.box_delta)
    _check_unit_sizes(units, hand_spec, box_rays)
    return units


def _check_unit_sizes(units: Sequence[UnitSpec], hand: Any, box_rays: int | None = None) -> None:
    """Refuse a sweep whose first unit of work would hold more than
    :data:`~planner.plan.sweep.MAX_UNIT_CANDIDATES` candidates (:func:`~planner.plan.sweep.check_unit_size`);
    ``box_rays``: the box sampler's on the one object of the run (a batch's units check their own)."""
    for settings in {u.settings.digest: u.settings for u in units if u.chunk == 0}.values():
        names = list(settings.preshapes) if settings.preshapes else None
        check_unit_size(settings, sweep_preshapes(hand, names, settings.support() is not None), box_rays)


def table_supports(obj: PreparedObject, poses: int) -> list[Support]:
    """The table tops under the object in its ``poses`` most probable resting
    poses (:mod:`planner.geometry.stable`), most probable first."""
    from planner.geometry.stable import resting_poses
    from planner.geometry.support import Support

    return [Support.resting(r.pose) for r in resting_poses(obj.mesh, obj.com, poses)]


def _stored_names(db: Database, units: Sequence[UnitSpec]) -> list[UnitSpec]:
    """The units, a mesh file's under the name the database already stores it by (from that file at that scale)
    where this run names it otherwise: runs before 2026-12-05 prefixed the folders of every file of a run in which
    two files shared a stem, so a resume of such a run finds its objects, not new ones of the same files. Not where
    the stored name is another file's name in this run, nor another name than the file's (a symlink's to it)."""
    from planner.specs.objects import OBJECT_SUFFIXES, file_named

    stored = db.names_by_source()
    if not stored:
        return list(units)
    taken = {u.label or u.object_name for u in units}
    renamed: dict[str, str] = {}
    for unit in units:
        label = unit.label or unit.object_name
        if label in renamed or Path(unit.object_name).suffix.lower() not in OBJECT_SUFFIXES:
            continue
        named = Path(unit.object_name).expanduser()
        names = stored.get((str(file_named(unit.object_name)), unit.scale or 1.0), [])
        # the file's own name, folder-prefixed: not another link's name to the same file (a link is its own object)
        other = [n for n in names if n not in taken and n.rsplit("/", 1)[-1] in (named.stem, named.name)]
        if names and label not in names and other:
            renamed[label] = other[0]
    return [replaced(u, label=renamed.get(u.label or u.object_name, u.label)) for u in units]


def _check_stored(db: Database, units: Sequence[UnitSpec], todo: Sequence[UnitSpec], flags: Physical) -> None:
    """Refuse to add grasps of an object stored under the same name at
    another mass, density, friction or up, or from another mesh or with other
    mass properties (:func:`planner.db.objects.differs`) than its stored
    grasps were planned and measured on: one name, one object. The mesh is
    prepared and compared for the objects with units ``todo``; an object
    whose units are all done is compared by its file and scale, and prepared
    only where those moved or the file (or its sidecar, or the manifest whose line gave it: a ``com=`` taken
    out) was modified since its last unit finished (its mtime: a copy that keeps an older mtime is not seen; a
    sidecar removed: its folder's). An
    object whose mesh no longer loads is left to its units (stored as
    failed). ``flags``: the run's values (a manifest line's replace them)."""
    from planner.db.objects import differs
    from planner.errors import PlannerError
    from planner.geometry.solid import prepare
    from planner.record.field import COM_TOL
    from planner.specs.object_files import edited_since, sidecar_changed

    running = {u.label or u.object_name for u in todo}
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
        if row.up != spec.up:  # said where it differs
            stored["up"], given["up"] = row.up, spec.up  # type: ignore[assignment]
        if any(given[k] != stored[k] if k == "up" else not math.isclose(given[k], stored[k], rel_tol=PROPERTY_RTOL)
               for k in given):
            def text(values: dict[str, float]) -> str:
                return ", ".join(f"{k} {v:g}" if k != "up" else f"up {v}" for k, v in values.items())

            how = f"up={row.up} on its manifest line" if unit.physical.up not in (None, flags.up) else f"--up {row.up}"
            keep = f", or give {how} to go on with it (a .glb/.gltf stored before schema v12 is +z)" \
                if "up" in given else ""
            raise InputError(f"object '{name}' is stored in {db.path} with {text(stored)}, this run gives "
                             f"{text(given)}{from_files(unit.object_name, spec, unit.physical)}; its grasps "
                             "were measured at the stored values: use another --db, or name the object apart (copy "
                             f"the mesh under another name){keep}")
        if name not in running and spec.user_file and row.source == spec.source and row.scale == spec.scale \
                and row.geometry == spec.geometry and (spec.com is None or math.dist(spec.com, row.com) <= COM_TOL) \
                and not edited_since(Path(spec.source), db.last_finished(name), spec.geometry) \
                and not sidecar_changed(Path(spec.source), db.last_finished(name)) \
                and not (unit.manifest and edited_since(Path(unit.manifest), db.last_finished(name))):
            continue  # nothing of it runs; it names the stored file and sidecar (and manifest), unchanged since
        try:
            why = differs(row, prepare(spec))
        except PlannerError:
            continue
        if why:
            raise InputError(f"object '{name}' is stored in {db.path} {why}: its grasps were planned on the stored "
                             "one; use another --db, or name the object apart (copy the mesh under another name)")


def generate(names: Sequence[str], hand: str, *, db_path: Path = DEFAULT_DB, settings: SweepSettings | None = None,
             seed: int = 0, workers: int = 1, scale: float | None = None, rule: RankingRule | None = None,
             use_ray: bool = False, ray_address: str | None = None, unit_timeout: float | None = None,
             progress: Callable[[GenerateProgress], None] | None = None,
             mass: float | None = None, density: float | None = None, friction: float | None = None,
             up: str | None = None, geometry: str | None = None, on_table: int = 0, replace: bool = False
             ) -> Summary:
    """Build (or extend) a grasp database; finished units are skipped, so a
    run that was killed resumes when called again. Units run in this process
    (``workers`` 1), in a crash-safe pool of ``workers`` processes, or on Ray
    (:func:`planner.run.pool.execute`); a unit whose worker dies twice, or
    that fails, is stored as failed with its error and the batch goes on.
    ``mass`` [kg] or ``density`` [kg/m^3], ``friction``, ``up`` (an axis,
    :mod:`planner.specs.up`) and ``geometry`` (a URDF file's elements) apply to every object except where a
    manifest line gives its own (see :mod:`planner.specs.objects`); an object stored at other values is refused.
    ``on_table`` > 0: plan on the table in each object's ``on_table`` most
    probable resting poses (the grasps keep the hand off the table and record
    its plane, ``table_plane``), not on the object alone.
    ``progress(GenerateProgress)`` once the work is planned, then as it goes.
    An object swept for ``hand`` with ``seed`` and other settings that try
    the same candidates (another planner version, budget, reach settings...)
    is refused; ``replace`` sweeps it anew and removes the stored sweep (its
    grasps and their trials) once the new one is whole
    (:class:`planner.api.sweeps.Replacement`)."""
    from planner.run import pool
    from planner.run.progress import Tally

    if workers < 1:
        raise InputError(f"--workers must be at least 1, got {workers}")
    if unit_timeout is not None and not (math.isfinite(unit_timeout) and 0 < unit_timeout <= MAX_UNIT_TIMEOUT):
        raise InputError(f"--unit-timeout must be a positive number of seconds, at most {MAX_UNIT_TIMEOUT:,.0f} (a "
                         f"week), got {unit_timeout}")
    check_seed(seed)
    physical = Physical.checked({"mass": mass, "density": density, "friction": friction, "up": up,
                                 "geometry": geometry}, prefix="--")
    hand_spec = load_hand(hand)
    settings = (settings or SweepSettings()).resolved(hand_spec.sampler, hand_spec.settle,
                                                        hand_spec.settle_dynamics)
    units = plan_units(names, hand, settings, seed, scale, physical, on_table)
    summary = Summary()
    start = time.perf_counter()
    with open_for_writing(Path(db_path)) as db:
        check_hand_files(db, [hand])
        units = _stored_names(db, units)
        done = {d: db.units_done(hand, d, seed) for d in sorted({u.settings.digest for u in units})}
        todo = [u for u in units if (u.label, u.chunk) not in done[u.settings.digest]]
        _check_stored(db, units, todo, physical)
        replacing = Replacement(db, hand_spec, seed, units, todo, replace)  # refuses a second sweep
        replacing.ready()
        rule = rule or db.rule()
        db.apply_rule(rule)
        summary.skipped = len(units) - len(todo)
        working = {u.label or u.object_name for u in todo}
        summary.finished_before = list(dict.fromkeys(n for n in (u.label or u.object_name for u in units)
                                                     if n not in working))
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
            todo = [replaced(u, timeout=unit_timeout) for u in todo]
        hard_timeout = unit_timeout + UNIT_TIMEOUT_GRACE if unit_timeout else None
        ray = (ray_address or "local") if use_ray else None
        unit_result = _lazy("UnitResult")
        index, notes = {_unit_key(u): i for i, u in enumerate(todo)}, set[str]()
        with closing(pool.execute(_lazy("run_unit"), todo, workers, timeout=hard_timeout, ray=ray,
                                  progress=reported if progress else None)) as outcomes, _letting_go():
            for unit, outcome, seconds in outcomes:
                result = outcome if isinstance(outcome, unit_result) else unit_result(unit, error=str(outcome))
                prepare.said(result.notes, notes)
                db.write_unit(unit_row(result, seconds), result.obj, result.grasps, rule)
                replacing.stored(unit, bool(result.error))
                _tally(summary, result, seconds)
                finished += 1
                tally.finish(index[_unit_key(unit)])
                tell(result)
        summary.replaced = replacing.removed
    for row in summary.per_object:  # said by the library: under --quiet, --json and in the API it went unsaid
        if row["density"] is not None and (note := density_note(row["object"], row["mass"], row["density"])):
            prepare.warned(note)
    summary.seconds = time.perf_counter() - start
    return summary


@contextmanager
def _letting_go() -> Iterator[None]:
    """Units run in this process (``workers`` 1) keep their object's sampled antipodal pairs for its next unit
    (:func:`planner.plan.sampling.antipodal_once`; ~120 MB at 1,000,000 points): let go of them when the run ends,
    however it ends, rather than for as long as the caller lives."""
    try:
        yield
    finally:
        sampling = sys.modules.get("planner.plan.sampling")  # not loaded: nothing kept (and nothing to import)
        if sampling is not None:
            sampling.forget()


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
    summary.force_closure, summary.ends = summary.force_closure + result.force_closure, summary.ends + result.ends
    summary.rejected.update(result.rejected)
    row = next((r for r in summary.per_object if r["object"] == name), None)
    if row is None:
        row = {"object": name, "units": 0, "candidates": 0, "grasps": 0, "force_closure": 0, "ends": 0, "seconds": 0.0,
               "error": None, "mass": None, "friction": None, "density": None, "up": None}
        summary.per_object.append(row)
    if result.obj is not None:  # the values the grasps were measured at (flags, manifest, sidecar or defaults)
        row["mass"], row["friction"] = result.obj.mass, result.obj.friction
        row["density"], row["up"] = result.obj.mass / result.obj.volume, result.obj.spec.up
    row["units"] += 1
    row["candidates"] += result.candidates
    row["grasps"] += len(result.grasps)
    row["force_closure"] += result.force_closure
    row["ends"] += result.ends
    row["seconds"] = round(row["seconds"] + seconds, 3)
    row["error"] = row["error"] or result.error
