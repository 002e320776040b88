"""Import ACRONYM HDF5 grasp files (this project's exports or foreign ones).

Each file becomes one unit of work in the database (object, hand, settings = the import source and the file's
sha256, seed 0, chunk 0); importing the same file again finds the unit done and skips it. Grasp ``candidate`` (and
``seed``) as an own file gives them, else the row index in the file. Reading the file is the format's reader's
(:mod:`planner.datasets.registry`; ACRONYM's is :mod:`planner.datasets.acronym`).

- Hand: ``gripper/type`` ("panda" and "franka_panda" mean ``panda``; any other value must be a hand name) or
  ``--hand``.
- Object: ``--object`` (a built-in name or a mesh path; a mesh path gets the file's ``object/scale``), else
  ``object/name`` when it is a built-in name whose mesh is the file's (``object/mesh_sha256``, in this project's
  files since issue 12; without it, when the file's own ``object/file``, where found, is the built-in's mesh or
  none is found), else ``object/file`` with ``object/scale`` under the name ``object/name``, or the .h5 file's
  stem (ACRONYM names each file by category, mesh and scale: two scales of one mesh are two objects), relative
  paths looked up next to the .h5 file (this project's export folders: ``meshes/`` beside the .h5 files), then one
  folder up (ACRONYM keeps ``grasps/`` beside ``meshes/``), from the .h5 file's absolute path
  (:mod:`planner.datasets.file_objects`, which ``grasp calibrate`` shares). So a built-in object exported at
  another ``--scale``, or under a copied name, comes back as the mesh its grasps were planned on.
  The file's ``object/mass``, ``object/friction`` and ``object/up`` (this project's files) override the
  object's; a file without ``object/up`` leaves the object's own (its mesh file's: ``+z`` for an OBJ).
  Its ``object/com`` and ``object/inertia`` too where they are not its mesh's at uniform density (a URDF's or
  a sidecar's given when it was planned; only this project's files, those with ``object/mesh_sha256``).
- Poses: ``grasps/transforms @ inverse(export_frame)``, the file's ``grasps/export_frame`` if present, else the
  hand's.
- Files with this project's extras (qualities, joints, contacts) are imported losslessly, with their shake-test
  and robust-epsilon results.
  Foreign files, or any file with ``rescore``, are re-scored: the hand is put at each pose open as the file
  planned it where it says (this project's files: the row's ``joints_open`` of the hand's driven joints, inside
  their limits, with its ``preshape``'s closing) and that open hand is free of the object there, and closed from
  it (:meth:`Grasper.close_from`, as a sweep closes); else (ACRONYM's own files, whose ``gripper/configuration``
  is the full opening of every pose) with its widest preshape open, backed off along the approach while it
  collides (doubling 1 cm steps while under ``MAX_BACK_OFF``), and closed (:meth:`Grasper.close_at`); centred, its
  contacts read as patches, and evaluated by :func:`planner.plan.unit.grasp_quality` and
  :func:`planner.plan.measures.measure` (the same analytic measures and rule as a sweep); poses where the hand
  does not close on the object are counted by reason and dropped. The stored pose is the closed hand's (after
  back-off and centring), its open joints those it closed from; reachability is None. The file's own success
  labels (``flex/object_in_gripper``: FleX's, a user's outcomes) are kept with them (``file_labels``).
  Re-scoring runs in the crash-safe worker pool (:mod:`planner.run.pool`, ``workers`` processes) in units of
  :data:`RESCORE_CHUNK` poses; a file is written once all its poses are back, its grasps in file order. A file
  whose re-scoring fails (a worker died twice) is stored as a failed unit with its error, and the next import of
  it tries again.
"""

from __future__ import annotations

import hashlib
import json
import time
from collections import Counter
from collections.abc import Callable, Sequence
from contextlib import closing
from dataclasses import dataclass, field, replace
from functools import partial
from pathlib import Path

import numpy as np

from planner import prepare as preparing
from planner.datasets import formats
from planner.datasets.file_objects import HAND_ALIASES, hand_name, object_spec, replaced, unstated, unstated_up
from planner.datasets.import_checks import check_files, check_objects
from planner.datasets.import_result import ImportResult, ImportSettings
from planner.datasets.registry import Openings, Reader
from planner.db.hand_files import check_hand_files
from planner.db.ranking import RankingRule
from planner.db.store import Database, UnitRow, Validated, open_for_writing
from planner.errors import InputError
from planner.geometry.frames import approach_of
from planner.geometry.solid import PreparedObject, prepare
from planner.plan import grip
from planner.plan.closing import Closed, Grasper
from planner.plan.local_sdf import LocalSurface
from planner.plan.measures import measure, measured_later, resistance_program
from planner.plan.squeeze import squeezed
from planner.plan.unit import scored
from planner.plan.width import closed_width
from planner.record.grasp import Grasp
from planner.run import pool
from planner.sim import Sim
from planner.specs.hands import HandSpec, load_hand
from planner.specs.objects import ObjectSpec
from planner.specs.physical import check_physical
from planner.specs.preshapes import load_preshapes, sweep_preshapes
from planner.specs.up import up_axis

#: Every format with a reader (:mod:`planner.datasets.registry`).
FORMATS = formats.IMPORT_FORMATS
#: Friction cone edges of a re-scored grasp (the sweep's default).
CONE_EDGES = 8
#: [m] how far a re-scored hand may back off when it starts in collision.
MAX_BACK_OFF = 0.02
#: Poses per re-scoring unit of work: a few seconds of closing each, so two
#: workers share even a single file.
RESCORE_CHUNK = 50


@dataclass(frozen=True)
class _Plan:
    path: Path
    hand: HandSpec
    spec: ObjectSpec
    lossless: bool
    settings: ImportSettings
    reader: Reader
    #: the mass and friction, and the up, taken where the file gives none: said unless it is skipped
    notes: tuple[str, ...] = ()


def import_files(paths: Sequence[Path], db_path: Path, *, fmt: str = "acronym", hand: str | None = None,
                 object_name: str | None = None, rescore: bool = False, workers: int = 1,
                 progress: Callable[[ImportResult], None] | None = None, up: str | None = None,
                 mass: float | None = None, friction: float | None = None) -> list[ImportResult]:
    """Import grasp files into ``db_path`` (created if missing). Every file is checked before anything is written.
    Re-scoring runs in ``workers`` processes; ``progress`` gets each file as it is written, the list returned is
    in the order of ``paths``. ``up``, ``mass`` [kg], ``friction``: the objects' where a file gives none (ACRONYM's
    own meshes stand on ``"+y"``); a file that gives neither mass nor friction is said with the values taken."""
    reader = formats.reader(fmt)
    up = None if up is None else up_axis(up, "", "--up")
    check_physical(mass, None, friction, prefix="--")  # as the option given, not as a file's object's
    plans = [_plan(Path(p), fmt, reader, hand, object_name, rescore, up=up, given=(mass, friction)) for p in paths]
    first: dict[tuple[str, str, str], int] = {}  # a unit's first file in the command: the rest are said, not read
    same = {i: first.setdefault((plan.hand.name, plan.spec.name, plan.settings.digest), i) for i, plan in
            enumerate(plans)}
    # every file's poses (and a lossless file's joints and contacts) read and checked before the database is opened:
    # a refused import (a NaN in grasps/transforms, a joint outside its limits, contacts that are not JSON) left an
    # empty database and its lock file at --db. A lossless file is read twice (here and when written) rather than
    # held: an export of many objects would be held whole
    poses = [plan.reader.poses(plan.path, plan.hand) if same[i] == i else None for i, plan in enumerate(plans)]
    openings = [None if plan.lossless or plan.reader.openings is None or same[i] != i else
                plan.reader.openings(plan.path, plan.hand) for i, plan in enumerate(plans)]
    labels = [[] if plan.lossless or plan.reader.labels is None or same[i] != i else plan.reader.labels(plan.path)
              for i, plan in enumerate(plans)]
    for plan, file_poses in zip(plans, poses):
        if file_poses is None:
            continue
        if plan.lossless:  # and its trials' columns
            plan.reader.grasps(plan.path, plan.hand, plan.spec.name, file_poses)
            plan.reader.simulation(plan.path)
    objs = check_files(plans)  # every file's: the same bytes beside another mesh (sidecar) are another object
    # a unit's up is told where any copy of its file's is (a sidecar's beside one; check_files: the same up)
    told = {same[i] for i, plan in enumerate(plans) if plan.settings.up_taken is None}
    plans = [replace(p, settings=replace(p.settings, up_taken=None)) if i in told else p for i, p in enumerate(plans)]
    results: dict[int, ImportResult] = {}

    def finish(index: int, result: ImportResult) -> None:
        results[index] = result
        if progress:
            progress(result)
        for j in (j for j, i in same.items() if i == index != j):  # said after the file it is the same as
            finish(j, ImportResult(plans[j].path, result.object, result.hand, 0, 0, result.rescored, True, {},
                                   result.error, same_as=result.path))

    with open_for_writing(Path(db_path)) as db:
        check_objects(db, plans, objs)
        check_hand_files(db, {p.hand.name for p in plans})
        rule = db.rule()
        db.apply_rule(rule)
        rescoring: dict[int, _Rescoring] = {}
        for i, plan in enumerate(plans):
            if same[i] != i:
                continue
            if (plan.spec.name, 0) in db.units_done(plan.hand.name, plan.settings.digest, 0):
                if plan.settings.up_taken is None:  # told now (--up, a sidecar): `validate` says it no more
                    db.up_told(plan.spec.name, plan.hand.name, plan.settings.digest)
                # its stored grasps whose file row has a label, where none of them carries it (not a file of
                # which no pose was kept, nor the labels of poses dropped: a new import keeps neither)
                stored = db.unit_file_labels(plan.spec.name, plan.hand.name, plan.settings.digest, 0)
                unstored = 0 if any(stored.values()) or not labels[i] else \
                    sum(labels[i][c] is not None for c in stored if 0 <= c < len(labels[i]))
                finish(i, ImportResult(plan.path, plan.spec.name, plan.hand.name, 0, 0, not plan.lossless, True, {},
                                       unstored_labels=unstored))
                continue
            for note in plan.notes:  # not for a file skipped as imported before: nothing of it is measured again
                preparing.warned(note)
            if plan.lossless:
                finish(i, _import_lossless(db, plan, rule))
            else:
                rescoring[i] = _Rescoring(plan, time.perf_counter(), poses[i], openings[i], labels[i])
        units = [unit for i, r in rescoring.items() for unit in r.units(i)]
        for i, r in rescoring.items():
            if r.complete:  # a file without poses
                finish(i, r.write(db, rule))
        said = set[str]()
        with closing(pool.execute(rescore_poses, units, workers)) as outcomes:
            for unit, outcome, _ in outcomes:
                preparing.said(outcome.notes if isinstance(outcome, Rescored) else [], said)
                r = rescoring[unit.file]
                r.add(unit, outcome)
                if r.complete:
                    finish(unit.file, r.write(db, rule))
    return [results[i] for i in range(len(plans))]


@dataclass(frozen=True)
class RescoreUnit:
    """A slice of one file's poses for a worker: ``poses`` (n, 4, 4) hand
    poses in the object frame [m], rows ``first .. first + n - 1`` of file
    number ``file`` of the import; ``openings``: theirs where the file gives them."""

    file: int
    first: int
    poses: np.ndarray
    hand: HandSpec
    spec: ObjectSpec
    openings: Openings | None = None


@dataclass
class Rescored:
    grasps: list[Grasp]
    rejected: Counter
    notes: list[str] = field(default_factory=list)  # what preparing the object noted where nothing showed it


def rescore_poses(unit: RescoreUnit) -> Rescored:
    """Close the hand at each pose of ``unit`` and score it (runs in workers)."""
    rejected, notes = Counter[str](), list[str]()
    with preparing.kept(notes):  # in a worker: said by the driver (preparing.said)
        grasps = _rescore(unit.poses, unit.hand, prepare(unit.spec), rejected, unit.first, unit.openings)
    return Rescored(grasps, rejected, notes)


@dataclass
class _Rescoring:
    """One file being re-scored: its slices come back in any order."""

    plan: _Plan
    start: float  # perf_counter() when the file was read
    poses: np.ndarray
    openings: Openings | None
    labels: list  # the file's own label of each pose (FileLabel or None), kept beside its re-scored grasp
    parts: dict[int, Rescored] = field(default_factory=dict)
    pending: int = 0
    error: str | None = None

    def units(self, index: int) -> list[RescoreUnit]:
        firsts = range(0, len(self.poses), RESCORE_CHUNK)
        self.pending = len(firsts)
        return [RescoreUnit(index, i, self.poses[i:i + RESCORE_CHUNK], self.plan.hand, self.plan.spec,
                            self.openings.rows(i, i + RESCORE_CHUNK) if self.openings else None) for i in firsts]

    @property
    def complete(self) -> bool:
        return self.pending == 0

    def add(self, unit: RescoreUnit, outcome: Rescored | pool.Failure) -> None:
        self.pending -= 1
        if isinstance(outcome, Rescored):
            self.parts[unit.first] = outcome
        else:
            self.error = self.error or f"poses {unit.first}-{unit.first + len(unit.poses) - 1}: {outcome}"

    def write(self, db: Database, rule: RankingRule) -> ImportResult:
        plan = self.plan
        obj = prepare(plan.spec)
        grasps = [g for first in sorted(self.parts) for g in self.parts[first].grasps] if not self.error else []
        grasps = [replace(g, file_label=self.labels[g.candidate]) for g in grasps] if any(self.labels) else grasps
        rejected: Counter = sum((p.rejected for p in self.parts.values()), Counter()) if not self.error else Counter()
        unit = UnitRow(obj.name, plan.hand.name, plan.settings.digest, plan.settings.to_json(), 0, 0, self.error,
                       len(self.poses), dict(rejected), time.perf_counter() - self.start)
        db.write_unit(unit, obj, grasps, rule)
        return ImportResult(plan.path, obj.name, plan.hand.name, len(grasps), sum(g.force_closure for g in grasps),
                            True, False, dict(rejected), self.error, _labels(grasps))


def _import_lossless(db: Database, plan: _Plan, rule: RankingRule) -> ImportResult:
    start = time.perf_counter()
    obj = prepare(plan.spec)
    poses = plan.reader.poses(plan.path, plan.hand)
    grasps = plan.reader.grasps(plan.path, plan.hand, obj.name, poses)
    unit = UnitRow(obj.name, plan.hand.name, plan.settings.digest, plan.settings.to_json(), 0, 0,
                   candidates=len(poses), seconds=time.perf_counter() - start)
    unit_id = db.write_unit(unit, obj, grasps, rule)
    _restore_simulation(db, plan, unit_id, obj.name, rule, [(g.candidate, g.squeezed_from_turn is not None)
                                                            for g in grasps])
    return ImportResult(plan.path, obj.name, plan.hand.name, len(grasps), sum(g.force_closure for g in grasps),
                        False, False, {}, labels=_labels(grasps))


def _labels(grasps: list[Grasp]) -> tuple[int, int]:
    """(held, dropped): the grasps stored with their file's label."""
    given = [g.file_label.success for g in grasps if g.file_label is not None]
    return sum(given), len(given) - sum(given)


def _restore_simulation(db: Database, plan: _Plan, unit_id: int, obj: str, rule: RankingRule,
                        candidates: list[tuple[int, bool]]) -> None:
    """Our own files carry shake-test results (PyBullet's and MuJoCo's) and robust epsilon per grasp: put them
    back into ``validation`` / ``mujoco`` / ``robust`` and re-score. ``candidates``: each file row's grasp (its
    candidate, whether it is a squeeze's end: :meth:`Database.grasp_ids`)."""
    results = plan.reader.simulation(plan.path)
    if not results:
        return
    source = json.dumps({"imported_from": str(plan.path)})
    ids = db.grasp_ids(unit_id)
    db.write_validation(obj, plan.hand.name, [Validated(ids[c], results[i][0], results[i][1], 0, source, source,
                                                        results[i][2], source) for i, c in enumerate(candidates)], rule)


def _plan(path: Path, fmt: str, reader: Reader, hand: str | None, object_name: str | None, rescore: bool,
          command: str = "import", up: str | None = None, given: tuple[float | None, float | None] = (None, None),
          note: bool = True) -> _Plan:
    header = reader.header(path)
    spec = load_hand(hand or hand_name(path, header.gripper))
    obj = object_spec(header, object_name, command, up, *given)
    # every measure and trial reads them: said; ``grasp calibrate`` has no --up (the shipped model's files stood on +z)
    untold = unstated_up(header, obj, up) if command == "import" else None
    lines = (unstated(header, obj, command, given), untold, replaced(header, obj))
    notes = tuple(line for line in lines if line) if note else ()
    lossless = not rescore and header.extras
    if lossless:  # its contacts, joints and measures are of the file's mesh and hand: stored as they are
        if header.mesh_sha256 and prepare(obj).mesh_hash != header.mesh_sha256:
            raise InputError(f"{path}: {obj.source or obj.name} is not the mesh this file's grasps were planned on "
                             "(object/mesh_sha256): their contacts and measures would be stored on another mesh; "
                             "give that mesh, or pass --rescore to re-score the poses on this one")
        named = HAND_ALIASES.get(header.gripper.lower(), header.gripper)
        if hand is not None and header.gripper and named != spec.name:
            raise InputError(f"{path}: its grasps are the {header.gripper}'s (joints, contacts); pass --rescore to "
                             f"re-score the poses with hand '{spec.name}'")
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    settings = ImportSettings(fmt, str(path), digest.hexdigest(), not lossless, obj.up if untold else None)
    return _Plan(path, spec, obj, lossless, settings, reader, notes)


def _rescore(poses: np.ndarray, hand: HandSpec, obj: PreparedObject, rejected: Counter, first: int = 0,
             openings: Openings | None = None) -> list[Grasp]:
    """Grasps of the poses where the hand closes on the object, from ``openings`` where given (module docstring);
    candidate = ``first`` + the pose's row in ``poses``. Their weight resistances are solved together once the
    poses are closed (:func:`~planner.plan.measures.measured_later`, as a sweep's)."""
    widest = hand.widest(sweep_preshapes(hand))
    shapes = {s.name: s for s in load_preshapes(hand)}
    out: list[Grasp] = []
    with Sim() as sim, measured_later(out, {"quality": 0.0}) as later:
        grasper = Grasper.for_object(sim, hand, obj)
        gripping = grip.GripSurface(obj.mesh, normals_at=grasper.normals_at())  # the exact surface
        local = LocalSurface(hand, obj.mesh if grasper.mesh is None else grasper.mesh)  # a large mesh's proxy
        for i, pose in enumerate(poses, start=first):
            given = None if openings is None else openings.at(hand, i - first)
            if given is not None and not grasper.overlaps_at(pose, given[1]):
                shape = shapes.get(given[0], widest)
                closed = grasper.close_from(pose, shape, given[1])
            else:
                shape, closed = widest, grasper.close_at(pose, widest, MAX_BACK_OFF)
            if not isinstance(closed, Closed):
                rejected[closed.reason] += 1
                continue
            q = scored(closed.contacts, hand, obj, CONE_EDGES, rejected)
            if q is None:
                continue
            width = closed_width(hand, closed.closed_joints)
            squeeze = squeezed(grasper, closed, shape, q, lambda c: scored(c, hand, obj, CONE_EDGES, Counter(), False))
            at = (closed.contacts, closed.frames, hand, shape, closed.closed_joints, obj)
            gripped = grip.measure(hand, gripping, closed.contacts, closed.link_poses or {}, obj.com, obj.up)
            waiting = (resistance_program(*at), partial(measure, *at, width, grip=gripped,  # type: ignore[arg-type]
                                                        squeeze=squeeze), (local, closed.pose))
            point, direction, roll = approach_of(closed.pose, hand.approach, shape.tcp)
            out.append(Grasp(
                object=obj.name, hand=hand.name, preshape=shape.name, candidate=i, seed=0,
                approach_point=point, approach_dir=direction, roll=roll, standoff=0.0, pose=closed.pose,
                open_joints=closed.open_joints, closed_joints=closed.closed_joints,
                width=width, contacts=closed.contacts, epsilon=q.epsilon, volume=q.volume,
                force_closure=q.force_closure, measures=None))
            later.append((len(out) - 1, *waiting))
    return out


def read_for_rescoring(path: Path, hand: str | None = None, fmt: str = "acronym", note: bool = False
                       ) -> tuple[HandSpec, ObjectSpec, np.ndarray]:
    """The hand, the object (with the file's mass and friction) and the
    (n, 4, 4) hand poses of a grasp file, as ``--rescore`` reads them; ``note``: say the mass and friction taken
    where the file gives none."""
    reader = formats.reader(fmt)
    plan = _plan(Path(path), fmt, reader, hand, None, True, "calibrate", note=note)
    for line in plan.notes:
        preparing.warned(line)
    return plan.hand, plan.spec, reader.poses(plan.path, plan.hand)
