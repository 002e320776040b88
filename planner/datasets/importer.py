"""Import ACRONYM HDF5 grasp files (this project's exports or foreign ones).

Each file becomes one unit of work in the database (object, hand, settings
= the import source and the file's sha256, seed 0, chunk 0), written by
:func:`planner.db.writer.write_unit`; importing the same file again finds the
unit done and skips it. Grasp ``candidate`` = the row index in the file.

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
  imported losslessly. Foreign files, or any file with ``rescore``, are
  re-scored: the hand is put at each pose with its widest preshape open,
  backed off along the approach while it collides (doubling 1 cm steps while
  under ``MAX_BACK_OFF``), closed and centred (:meth:`Grasper.close_at`), and
  evaluated by :func:`planner.plan.unit.grasp_quality`; poses where the hand does
  not close on the object are counted by reason and dropped. The stored pose
  is the closed hand's (after back-off and centring). Reachability is not
  computed (None).
"""

from __future__ import annotations

import hashlib
import json
import math
import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import numpy as np

from planner.db.lock import writer_lock
from planner.db.ranking import RankingRule
from planner.db.store import open_db
from planner.db.writer import apply_rule, rescore, write_unit
from planner.errors import InputError, UnknownNameError
from planner.geometry.frames import hand_rotation, tangent_basis
from planner.geometry.solid import PreparedObject, prepare
from planner.plan.closing import Closed, Grasper
from planner.plan.contacts import HandContacts
from planner.plan.sweep import SweepSettings
from planner.plan.unit import GraspRecord, UnitResult, UnitSpec, grasp_quality
from planner.sim import Sim
from planner.specs.hands import HandSpec, hand_names, load_hand
from planner.specs.objects import RANDOM_PREFIX, ObjectSpec, builtin_specs, resolve_spec
from planner.specs.preshapes import Preshape, load_preshapes

FORMATS = ("acronym",)
HAND_ALIASES = {"panda": "panda", "franka_panda": "panda"}
#: Datasets whose presence marks a file with this project's extras.
EXTRAS = ("qualities/epsilon", "qualities/volume", "qualities/force_closure", "joint_names", "joints_closed",
          "joints_open", "contacts")
CONE_EDGES = 8
#: [m] how far a re-scored hand may back off when it starts in collision.
MAX_BACK_OFF = 0.02
#: Bumped when an import of the same file would store different grasps.
IMPORT_VERSION = 1
#: Rotation rows of a transform may deviate from orthonormal by this much.
ROTATION_TOL = 1e-5


@dataclass(frozen=True)
class ImportSettings:
    """The settings of an import unit. Stands in for :class:`SweepSettings`
    in ``write_unit``, which uses only ``digest`` and ``to_json``."""

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
    h5py = _h5py()
    plans = [_plan(h5py, Path(p), hand, object_name, rescore) for p in paths]
    results = []
    with writer_lock(Path(db_path)), open_db(Path(db_path)) as db:
        rule = RankingRule.from_json(db.meta("ranking"))
        apply_rule(db, rule)
        for plan in plans:
            if (plan.spec.name, 0) in db.units_done(plan.hand.name, plan.settings.digest, 0):
                result = ImportResult(plan.path, plan.spec.name, plan.hand.name, 0, 0, not plan.lossless, True, {})
            else:
                start = time.perf_counter()
                unit = _read(h5py, plan)
                write_unit(db, unit, time.perf_counter() - start, rule)
                if plan.lossless:
                    _restore_simulation(db, h5py, plan, rule)
                result = ImportResult(plan.path, plan.spec.name, plan.hand.name, len(unit.grasps),
                                      unit.force_closure, not plan.lossless, False, dict(unit.rejected))
            results.append(result)
            if progress:
                progress(result)
    return results


def _restore_simulation(db: Any, h5py: Any, plan: _Plan, rule: Any) -> None:
    """Our own files carry shake-test results and robust epsilon per grasp:
    put them back into ``validation`` / ``robust`` and re-score."""
    with h5py.File(plan.path, "r") as f:
        q = f["grasps/qualities"]
        if "simulated_success" not in q:
            return
        success = np.asarray(q["simulated_success"][()], int)
        flex = q["flex"] if "flex" in q else {}
        motion = {k: np.asarray(flex[f"object_motion_during_{k}"][()], float) if f"object_motion_during_{k}" in flex
                  else np.full(len(success), np.nan) for k in ("closing_linear", "closing_angular",
                                                               "shaking_linear", "shaking_angular")}
        robust_mean = np.asarray(q["robust_epsilon_mean"][()], float) if "robust_epsilon_mean" in q else None
        robust_q = np.asarray(q["robust_epsilon_quantile"][()], float) if "robust_epsilon_quantile" in q else None
    source = json.dumps({"imported_from": str(plan.path)})
    with db.transaction() as conn:
        unit = conn.execute("SELECT id FROM units WHERE object = ? AND hand = ? AND settings_hash = ? AND chunk = 0",
                            (plan.spec.name, plan.hand.name, plan.settings.digest)).fetchone()
        ids = dict(conn.execute("SELECT candidate, id FROM grasps WHERE unit_id = ?", (unit[0],)).fetchall())
        for i, grasp_id in ids.items():
            if success[i] >= 0:
                conn.execute("INSERT OR REPLACE INTO validation VALUES (?,?,?,?,?,?,?,?,?)",
                             (grasp_id, int(success[i]), -1, *(float(np.nan_to_num(motion[k][i], nan=-1.0))
                                                               for k in ("closing_linear", "closing_angular",
                                                                         "shaking_linear", "shaking_angular")),
                              0, source))
            if robust_mean is not None and robust_q is not None and np.isfinite(robust_mean[i]):
                conn.execute("INSERT OR REPLACE INTO robust VALUES (?,?,?,?,?,?)",
                             (grasp_id, float(robust_mean[i]), float(robust_q[i]), 0, 0, source))
        rescore(conn, rule, plan.spec.name, plan.hand.name)


def _h5py() -> Any:
    try:
        import h5py
    except ImportError:
        raise InputError("importing ACRONYM files needs h5py: pip install -e '.[export]'") from None
    return h5py


def _plan(h5py: Any, path: Path, hand: str | None, object_name: str | None, rescore: bool) -> _Plan:
    if not path.is_file():
        raise InputError(f"{path}: file not found")
    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        raise InputError(f"{path}: not an HDF5 file ({exc})") from None
    with f:
        for key in ("grasps/transforms", "gripper/type"):
            if key not in f:
                raise InputError(f"{path}: no '{key}' dataset; not an ACRONYM grasp file")
        spec = load_hand(hand or _hand_name(path, _text(f["gripper/type"][()])))
        obj = _object_spec(path, f, object_name)
        lossless = not rescore and all(f"grasps/{k}" in f for k in EXTRAS)
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


def _object_spec(path: Path, f: Any, object_name: str | None) -> ObjectSpec:
    props = {k: _positive(f, f"object/{k}") for k in ("mass", "friction")}
    scale = _positive(f, "object/scale")
    if object_name is not None:
        if _registered(object_name):
            return resolve_spec(object_name, **props)
        return resolve_spec(object_name, scale=scale, **props)
    label = _text(f["object/name"][()]) if "object/name" in f else None
    if label is not None and _registered(label):
        return resolve_spec(label, **props)
    if "object/file" not in f:
        raise InputError(f"{path}: no object/file; pass --object NAME or a mesh path")
    mesh = _text(f["object/file"][()])
    tried = [path.parent / mesh, path.parent.parent / mesh]
    found = next((p for p in tried if p.is_file()), None)
    if found is None:
        raise InputError(f"{path}: object/file '{mesh}' not found (looked at {', '.join(map(str, tried))}); "
                         "pass --object NAME or a mesh path")
    return resolve_spec(str(found), scale=scale, label=label, **props)


def _registered(name: str) -> bool:
    """A built-in or random_NNN name: its own mesh and scale, not the file's."""
    prefix = RANDOM_PREFIX
    return name in builtin_specs() or (name.startswith(prefix) and name[len(prefix):].isdigit())


def _positive(f: Any, key: str) -> float | None:
    if key not in f:
        return None
    value = float(np.asarray(f[key][()]).reshape(-1)[0])
    return value if math.isfinite(value) and value > 0 else None


def _text(value: object) -> str:
    return value.decode() if isinstance(value, bytes) else str(value)


def _read(h5py: Any, plan: _Plan) -> UnitResult:
    obj = prepare(plan.spec)
    unit = UnitSpec(str(plan.path), plan.hand.name, cast(SweepSettings, plan.settings), 0, label=obj.name)
    result = UnitResult(unit, obj)
    with h5py.File(plan.path, "r") as f:
        g = f["grasps"]
        frame = np.asarray(g["export_frame"][()], float) if "export_frame" in g else plan.hand.export_frame
        poses = _poses(plan.path, np.asarray(g["transforms"][()], float)) @ np.linalg.inv(frame)
        result.candidates = len(poses)
        if plan.lossless:
            result.grasps = _lossless(plan.path, g, poses, plan.hand)
        else:
            result.grasps = _rescore(poses, plan.hand, obj, result.rejected)
    return result


def _poses(path: Path, transforms: np.ndarray) -> np.ndarray:
    """(N, 4, 4) checked rigid transforms."""
    if transforms.ndim != 3 or transforms.shape[1:] != (4, 4):
        raise InputError(f"{path}: grasps/transforms has shape {transforms.shape}; expected (N, 4, 4)")
    rot = transforms[:, :3, :3]
    bad = ~np.isfinite(transforms).all(axis=(1, 2))
    bad |= np.abs(rot @ rot.transpose(0, 2, 1) - np.eye(3)).max(axis=(1, 2), initial=0) > ROTATION_TOL
    bad |= np.abs(transforms[:, 3] - [0, 0, 0, 1]).max(axis=1, initial=0) > ROTATION_TOL
    if bad.any():
        raise InputError(f"{path}: grasps/transforms row {int(np.argmax(bad))} is not a rigid transform")
    return transforms


def _lossless(path: Path, g: Any, poses: np.ndarray, hand: HandSpec) -> list[GraspRecord]:
    q = g["qualities"]
    n = len(poses)
    names = list(g["joint_names"].asstr()[()])
    closed, opened = g["joints_closed"][()], g["joints_open"][()]
    col = {k: (q[k][()] if k in q else np.full(n, np.nan))  # whole columns: h5py indexing per row is slow
           for k in ("epsilon", "volume", "force_closure", "reachability", "manipulability")}
    width = g["width"][()] if "width" in g else np.full(n, np.nan)
    preshape = g["preshape"].asstr()[()] if "preshape" in g else ["imported"] * n
    approach_dir = g["approach_dir"][()] if "approach_dir" in g else poses[:, :3, :3] @ hand.approach
    approach_point = g["approach_point"][()] if "approach_point" in g else poses[:, :3, :3] @ hand.tcp + poses[:, :3, 3]
    roll = g["roll"][()] if "roll" in g else [_roll(p[:3, :3], hand, d) for p, d in zip(poses, approach_dir)]
    standoff = g["standoff"][()] if "standoff" in g else np.zeros(n)
    contacts = g["contacts"].asstr()[()]
    out = []
    for i in range(n):
        joints = _joints(names, closed[i])
        out.append(GraspRecord(
            candidate=i, preshape=str(preshape[i]), approach_point=np.asarray(approach_point[i], float),
            approach_dir=np.asarray(approach_dir[i], float), roll=float(roll[i]), standoff=float(standoff[i]),
            closed=Closed(poses[i], _joints(names, opened[i]), joints, _contacts(path, json.loads(contacts[i]), hand)),
            epsilon=float(col["epsilon"][i]), volume=float(col["volume"][i]),
            force_closure=bool(col["force_closure"][i]),
            width=_maybe(width[i]), reachability=_maybe(col["reachability"][i]),
            manipulability=_maybe(col["manipulability"][i])))
    return out


def _joints(names: list[str], values: np.ndarray) -> dict[str, float]:
    return {k: float(v) for k, v in zip(names, values) if math.isfinite(v)}


def _maybe(value: float) -> float | None:
    return None if math.isnan(value) else float(value)


def _contacts(path: Path, items: list[dict], hand: HandSpec) -> HandContacts:
    links = tuple(c["link"] for c in items)
    models = [hand.contacts.get(link) for link in links]
    if None in models:
        raise InputError(f"{path}: contact on link {sorted(set(links) - set(hand.contacts))} of hand '{hand.name}', "
                         f"which has contact links {', '.join(hand.contact_links)}")
    return HandContacts(np.array([c["point"] for c in items], float).reshape(-1, 3),
                    np.array([c["normal"] for c in items], float).reshape(-1, 3), links,
                    tuple(m.model for m in models), np.array([m.torsion for m in models], float))  # type: ignore[union-attr]


def _rescore(poses: np.ndarray, hand: HandSpec, obj: PreparedObject, rejected: Counter) -> list[GraspRecord]:
    shape = widest_preshape(hand)
    out = []
    with Sim() as sim:
        grasper = Grasper(sim, hand, sim.add_static_mesh(obj.mesh.vertices, obj.mesh.faces))
        for i, pose in enumerate(poses):
            closed = grasper.close_at(pose, shape, MAX_BACK_OFF)
            if not isinstance(closed, Closed):
                rejected[closed.reason] += 1
                continue
            q = grasp_quality(closed, obj, CONE_EDGES)
            p = closed.pose
            direction = p[:3, :3] @ hand.approach
            width = sum(closed.closed_joints[j.name] for j in hand.joints if j.kind == "prismatic")
            out.append(GraspRecord(
                candidate=i, preshape=shape.name, approach_point=p[:3, :3] @ shape.tcp + p[:3, 3],
                approach_dir=direction, roll=_roll(p[:3, :3], hand, direction), standoff=0.0, closed=closed,
                epsilon=q.epsilon, volume=q.volume, force_closure=q.force_closure,
                width=float(width) if hand.centering else None))
    return out


def widest_preshape(hand: HandSpec) -> Preshape:
    """The most open preshape: largest travel against the closing synergy."""
    return max(load_preshapes(hand), key=lambda s: -sum(r * s.joints[j] for j, r in s.close.items()))


def _roll(rotation: np.ndarray, hand: HandSpec, direction: np.ndarray) -> float:
    """The roll [rad] with ``hand_rotation(hand.approach, direction, roll) == rotation``."""
    d = np.asarray(direction, float) / np.linalg.norm(direction)
    spin = rotation @ hand_rotation(hand.approach, d, 0.0).T
    l_vec, _ = tangent_basis(d)
    v = spin @ l_vec
    return float(np.arctan2(v @ np.cross(d, l_vec), v @ l_vec))
