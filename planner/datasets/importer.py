"""Import ACRONYM HDF5 grasp files (this project's exports or foreign ones).

Each file becomes one unit of work in the database (object, hand, settings
= the import source and the file's sha256, seed 0, chunk 0); importing the
same file again finds the unit done and skips it. Grasp ``candidate`` = the
row index in the file. Reading the file is :mod:`planner.datasets.acronym`'s.

- Hand: ``gripper/type`` ("panda" and "franka_panda" mean ``panda``; any
  other value must be a hand name) or ``--hand``.
- Object: ``--object`` (a built-in name or a mesh path; a mesh path gets the
  file's ``object/scale``), else ``object/name`` when it is a built-in name
  (this project's files), else ``object/file`` with ``object/scale``,
  relative paths looked up next to the .h5 file and then one folder up
  (ACRONYM keeps ``grasps/`` beside ``meshes/``). The file's ``object/mass``
  and ``object/friction`` override the object's.
- Poses: ``grasps/transforms @ inverse(export_frame)``, the file's
  ``grasps/export_frame`` if present, else the hand's.
- Files with this project's extras (qualities, joints, contacts) are
  imported losslessly, with their shake-test and robust-epsilon results.
  Foreign files, or any file with ``rescore``, are re-scored: the hand is put
  at each pose with its widest preshape open, backed off along the approach
  while it collides (doubling 1 cm steps while under ``MAX_BACK_OFF``),
  closed and centred (:meth:`Grasper.close_at`), its contacts read as
  patches, and evaluated by :func:`planner.plan.unit.grasp_quality` and
  :func:`planner.plan.measures.measure` (the same analytic measures and rule
  as a sweep); poses where the hand does not
  close on the object are counted by reason and dropped. The stored pose is
  the closed hand's (after back-off and centring). Reachability is not
  computed (None).
"""

from __future__ import annotations

import hashlib
import json
import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from planner.datasets import acronym
from planner.datasets.acronym import AcronymHeader
from planner.db.lock import writer_lock
from planner.db.ranking import RankingRule
from planner.db.store import Database, UnitRow, Validated, open_db
from planner.errors import InputError, UnknownNameError
from planner.geometry.frames import roll_about
from planner.geometry.solid import PreparedObject, prepare
from planner.grasp import Grasp
from planner.plan.closing import Closed, Grasper
from planner.plan.measures import measure
from planner.plan.unit import closed_width, grasp_quality
from planner.sim import Sim
from planner.specs.hands import HandSpec, hand_names, load_hand
from planner.specs.objects import ObjectSpec, is_registered, resolve_spec
from planner.specs.preshapes import Preshape, load_preshapes

FORMATS = ("acronym",)
HAND_ALIASES = {"panda": "panda", "franka_panda": "panda"}
#: Friction cone edges of a re-scored grasp (the sweep's default).
CONE_EDGES = 8
#: [m] how far a re-scored hand may back off when it starts in collision.
MAX_BACK_OFF = 0.02
#: Bumped when an import of the same file would store different grasps.
IMPORT_VERSION = 1


@dataclass(frozen=True)
class ImportSettings:
    """The settings of an import unit (the ``units`` row's settings and hash)."""

    format: str
    file: str
    sha256: str
    rescore: bool

    def to_json(self) -> str:
        return json.dumps({"import": self.format, "file": self.file, "sha256": self.sha256,
                           "rescore": self.rescore, "import_version": IMPORT_VERSION}, sort_keys=True)

    @property
    def digest(self) -> str:
        """Content, not path: the same file imported from elsewhere is the same unit."""
        key = json.dumps([self.format, self.sha256, self.rescore, IMPORT_VERSION])
        return hashlib.sha256(key.encode()).hexdigest()[:16]


@dataclass(frozen=True)
class ImportResult:
    path: Path
    object: str
    hand: str
    grasps: int
    force_closure: int
    rescored: bool
    skipped: bool  # already imported: nothing written
    rejected: dict[str, int]

    def to_json(self) -> dict:
        return {**self.__dict__, "path": str(self.path)}


@dataclass(frozen=True)
class _Plan:
    path: Path
    hand: HandSpec
    spec: ObjectSpec
    lossless: bool
    settings: ImportSettings


def import_files(paths: Sequence[Path], db_path: Path, *, fmt: str = "acronym", hand: str | None = None,
                 object_name: str | None = None, rescore: bool = False,
                 progress: Callable[[ImportResult], None] | None = None) -> list[ImportResult]:
    """Import grasp files into ``db_path`` (created if missing). Every file is
    checked before anything is written."""
    if fmt not in FORMATS:
        raise UnknownNameError("import format", fmt, FORMATS)
    _require_h5py()
    plans = [_plan(Path(p), hand, object_name, rescore) for p in paths]
    results = []
    with writer_lock(Path(db_path)), open_db(Path(db_path)) as db:
        rule = db.rule()
        db.apply_rule(rule)
        for plan in plans:
            if (plan.spec.name, 0) in db.units_done(plan.hand.name, plan.settings.digest, 0):
                result = ImportResult(plan.path, plan.spec.name, plan.hand.name, 0, 0, not plan.lossless, True, {})
            else:
                result = _import(db, plan, rule)
            results.append(result)
            if progress:
                progress(result)
    return results


def _import(db: Database, plan: _Plan, rule: RankingRule) -> ImportResult:
    start = time.perf_counter()
    obj = prepare(plan.spec)
    poses = acronym.read_poses(plan.path, plan.hand)
    rejected: Counter = Counter()
    if plan.lossless:
        grasps = acronym.read_grasps(plan.path, plan.hand, obj.name, poses)
    else:
        grasps = _rescore(poses, plan.hand, obj, rejected)
    unit = UnitRow(obj.name, plan.hand.name, plan.settings.digest, plan.settings.to_json(), 0, 0,
                   candidates=len(poses), rejected=dict(rejected), seconds=time.perf_counter() - start)
    unit_id = db.write_unit(unit, obj, grasps, rule)
    if plan.lossless:
        _restore_simulation(db, plan, unit_id, obj.name, rule)
    return ImportResult(plan.path, obj.name, plan.hand.name, len(grasps), sum(g.force_closure for g in grasps),
                        not plan.lossless, False, dict(rejected))


def _restore_simulation(db: Database, plan: _Plan, unit_id: int, obj: str, rule: RankingRule) -> None:
    """Our own files carry shake-test results and robust epsilon per grasp:
    put them back into ``validation`` / ``robust`` and re-score."""
    results = acronym.read_simulation(plan.path)
    if not results:
        return
    source = json.dumps({"imported_from": str(plan.path)})
    ids = db.grasp_ids(unit_id)
    db.write_validation(obj, plan.hand.name, [Validated(grasp_id, *results[i], 0, source, source)
                                              for i, grasp_id in ids.items()], rule)


def _require_h5py() -> None:
    try:
        import h5py  # noqa: F401  (the ACRONYM reader needs it)
    except ImportError:
        raise InputError("importing ACRONYM files needs h5py: pip install -e '.[export]'") from None


def _plan(path: Path, hand: str | None, object_name: str | None, rescore: bool) -> _Plan:
    header = acronym.read_header(path)
    spec = load_hand(hand or _hand_name(path, header.gripper))
    obj = _object_spec(header, object_name)
    lossless = not rescore and header.extras
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return _Plan(path, spec, obj, lossless, ImportSettings("acronym", str(path), digest.hexdigest(), not lossless))


def _hand_name(path: Path, gripper: str) -> str:
    name = HAND_ALIASES.get(gripper.lower(), gripper)
    if name not in hand_names():
        raise InputError(f"{path}: gripper type '{gripper}' is not a known hand; pass --hand "
                         f"(available hands: {', '.join(hand_names())})")
    return name


def _object_spec(h: AcronymHeader, object_name: str | None) -> ObjectSpec:
    """The object an ACRONYM header names (see the module docstring)."""
    props = {"mass": h.mass, "friction": h.friction}
    if object_name is not None:
        if is_registered(object_name):
            return resolve_spec(object_name, **props)
        return resolve_spec(object_name, scale=h.scale, **props)
    label = h.object_name
    if label is not None and is_registered(label):
        return resolve_spec(label, **props)
    path, mesh = h.path, h.object_file
    if mesh is None:
        raise InputError(f"{path}: no object/file; pass --object NAME or a mesh path")
    tried = [path.parent / mesh, path.parent.parent / mesh]
    found = next((p for p in tried if p.is_file()), None)
    if found is None:
        raise InputError(f"{path}: object/file '{mesh}' not found (looked at {', '.join(map(str, tried))}); "
                         "pass --object NAME or a mesh path")
    return resolve_spec(str(found), scale=h.scale, label=label, **props)


def _rescore(poses: np.ndarray, hand: HandSpec, obj: PreparedObject, rejected: Counter) -> list[Grasp]:
    shape = widest_preshape(hand)
    out = []
    with Sim() as sim:
        grasper = Grasper.for_mesh(sim, hand, obj.mesh)
        for i, pose in enumerate(poses):
            closed = grasper.close_at(pose, shape, MAX_BACK_OFF)
            if not isinstance(closed, Closed):
                rejected[closed.reason] += 1
                continue
            q = grasp_quality(closed.contacts, hand, obj, CONE_EDGES)
            width = closed_width(hand, closed.closed_joints)
            m = measure(closed.contacts, closed.frames, hand, shape, closed.closed_joints, obj, width)  # type: ignore[arg-type]
            p = closed.pose
            direction = p[:3, :3] @ hand.approach
            out.append(Grasp(
                object=obj.name, hand=hand.name, preshape=shape.name, candidate=i, seed=0,
                approach_point=p[:3, :3] @ shape.tcp + p[:3, 3], approach_dir=direction,
                roll=roll_about(p[:3, :3], hand.approach, direction), standoff=0.0, pose=p,
                open_joints=closed.open_joints, closed_joints=closed.closed_joints,
                width=width, contacts=closed.contacts, epsilon=q.epsilon, volume=q.volume,
                force_closure=q.force_closure, measures=m))
    return out


def widest_preshape(hand: HandSpec) -> Preshape:
    """The most open preshape: largest travel against the closing synergy."""
    return max(load_preshapes(hand), key=lambda s: -sum(r * s.joints[j] for j, r in s.close.items()))
