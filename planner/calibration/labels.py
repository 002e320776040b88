"""Labelled grasp files (ACRONYM layout) as measures and labels.

Each file's poses are read and re-scored as ``grasp import --rescore`` does
(:func:`planner.datasets.importer.rescore_poses`: the hand closed at each
pose, from the opening the file planned it with where it gives one, else from
the widest preshape (ACRONYM's own files); contacts, epsilon and the analytic
measures, with the file's mass and friction); a seeded uniform sample of ``poses`` per file keeps the work
bounded. Poses where the hand does not close on the object are counted by
reason: they are never stored, so p_hold is not fitted on them.

The group of a grasp (its object, for folds grouped by object) is the mesh
file its file names (the same object at two scales is one group), or the
built-in object's name.

A file is known by its resolved path and shown by the shortest tail of it
that no other file given shares (:func:`label_names`: ``day1/grasps.h5``
and ``day2/grasps.h5``, ``a.h5`` alone where it is the only ``a.h5``); a
file given twice (``a.h5 ./a.h5``, overlapping globs) or a copy of one (the
same bytes under another name) is refused, since it would count twice.
Its pose sample is seeded by its stem (where it lies does not change it).

With ``trial`` > 0, a seeded sample of that many closed grasps per file is
also tried in a dynamic trial (``engine``: MuJoCo's or PyBullet's, as
``grasp validate`` runs it, at the file's mass and friction): their
verdicts are what a :class:`~planner.calibration.update.TrialUpdate` is
fitted on (p_hold given the verdict).
"""

from __future__ import annotations

import zlib
from collections import Counter
from collections.abc import Callable, Sequence
from contextlib import closing
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from planner import prepare
from planner.calibration import features
from planner.datasets import acronym, importer
from planner.errors import InputError
from planner.record.grasp import Grasp
from planner.run import pool
from planner.specs.hands import HandSpec
from planner.specs.objects import ObjectSpec


@dataclass(frozen=True)
class LabelledSet:
    """Closed, labelled grasps of several files.

    table: the measure table (name -> (n,)); labels (n,) 0/1; groups (n,)
    object (mesh) of each grasp; files (n,) the file of each grasp (its
    name as :func:`label_names` shows it, one per file); hand; sampled:
    poses sampled per file; rejected: why poses did not
    close, counted per reason over all files; verdicts (n,): 1 held, 0
    dropped in the dynamic trial ``engine`` (its record group: ``mujoco``
    or ``validation``), NaN not tried (None: no trial asked for); objects:
    per file, its object's properties (the names of
    :data:`~planner.calibration.logistic.DOMAIN`, their units), from which a
    fitted model's domain comes; hashes: per file, the sha256 of its bytes (where known: a fitted model records
    them beside the files' names).
    """

    table: dict[str, np.ndarray]
    labels: np.ndarray
    groups: tuple[str, ...]
    files: tuple[str, ...]
    hand: str
    sampled: dict[str, int] = field(default_factory=dict)
    rejected: dict[str, int] = field(default_factory=dict)
    verdicts: np.ndarray | None = None
    engine: str = ""
    objects: dict[str, dict[str, float]] = field(default_factory=dict)
    hashes: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        n = len(self.labels)
        if self.verdicts is not None and len(self.verdicts) != n:
            raise ValueError("LabelledSet: verdicts must have one entry per grasp (NaN: not tried)")
        if len(self.groups) != n or len(self.files) != n or any(len(v) != n for v in self.table.values()):
            raise ValueError("LabelledSet: table columns, labels, groups and files must have one entry per grasp")


def sample_rows(n: int, k: int | None, seed: int, stem: str) -> np.ndarray:
    """(min(k, n),) sorted rows of a file's n poses, seeded by the file's stem; all rows if ``k`` is None."""
    if k is None or k >= n:
        return np.arange(n)
    rng = np.random.default_rng([seed, zlib.crc32(stem.encode())])
    return np.sort(rng.choice(n, size=k, replace=False))


def labelled(paths: Sequence[Path], *, poses: int | None = 200, seed: int = 0, hand: str | None = None,
             workers: int = 1, progress: Callable[[Path, int, int], None] | None = None, trial: int = 0,
             engine: str = "mujoco") -> LabelledSet:
    """Re-score a sample of each file's poses and pair the closed ones with
    their labels; ``trial`` > 0: that many closed grasps per file tried in
    ``engine`` (module docstring)."""
    hand_name = check_labelled(paths, poses=poses, hand=hand, trial=trial, engine=engine)
    tables, labels, groups, files, verdicts = [], [], [], [], []
    sampled: dict[str, int] = {}
    objects: dict[str, dict[str, float]] = {}
    rejected: Counter = Counter()
    said = set[str]()
    hashes: dict[str, str] = {}
    for path, (name, digest) in zip(map(Path, paths), label_files(paths)):
        spec_hand, spec, all_poses = importer.read_for_rescoring(path, hand_name, note=True)
        y = acronym.read_labels(path)
        rows = sample_rows(len(all_poses), poses, seed, path.stem)
        sampled[name] = len(rows)
        chunk, openings = importer.RESCORE_CHUNK, acronym.read_openings(path, spec_hand)  # own files': as import's
        units = [importer.RescoreUnit(0, i, all_poses[rows[i:i + chunk]], spec_hand, spec,
                                      openings.take(rows[i:i + chunk])) for i in range(0, len(rows), chunk)]
        grasps = {}
        with closing(pool.execute(importer.rescore_poses, units, workers)) as outcomes:
            for _unit, outcome, _ in outcomes:
                if isinstance(outcome, pool.Failure):
                    raise InputError(f"{path}: re-scoring failed ({outcome})")
                prepare.said(outcome.notes, said)  # a mesh closed, bodies standing apart: in a worker, said here
                rejected.update(outcome.rejected)
                grasps.update({g.candidate: g for g in outcome.grasps})  # candidate = position in rows
        order = sorted(grasps)
        if order and trial:
            verdicts.append(_tried(spec_hand, spec, [grasps[i] for i in order], trial, seed, path.stem, engine))
        if order:
            objects[name], hashes[name] = object_properties(spec), digest
            tables.append(features.of_grasps([grasps[i] for i in order]))
            labels.append(y[rows[order]])
            groups += [group(spec)] * len(order)
            files += [name] * len(order)
        if progress:
            progress(path, len(order), len(rows))
    if not tables:
        raise InputError("no labelled pose closed on its object: nothing to calibrate on")
    table = {k: np.concatenate([t[k] for t in tables]) for k in features.TABLE}
    return LabelledSet(table, np.concatenate(labels), tuple(groups), tuple(files), hand_name, sampled,
                       dict(rejected), np.concatenate(verdicts) if trial else None,
                       TRIAL_GROUPS[engine] if trial else "", objects, hashes)


def label_names(paths: Sequence[Path]) -> list[str]:
    """Each file's name as shown and stored: the shortest tail of its resolved path that no other of ``paths``
    shares; a file given twice, or two files of the same bytes, are refused."""
    return [name for name, _ in label_files(paths)]


def label_files(paths: Sequence[Path]) -> list[tuple[str, str]]:
    """Each file's name (:func:`label_names`) and the sha256 of its bytes (:func:`file_digest`)."""
    resolved = [Path(p).resolve() for p in paths]
    seen: dict[Path, Path] = {}
    for given, path in zip(map(Path, paths), resolved):
        if path in seen:
            spelt = f" (as {seen[path]} and {given})" if seen[path] != given else ""
            raise InputError(f"{given}: given twice{spelt}: its labels would count twice; give each file once")
        seen[path] = given
    contents: dict[str, Path] = {}
    for given, path in zip(map(Path, paths), resolved):
        digest = file_digest(path)
        if digest in contents:
            raise InputError(f"{given}: the same bytes as {contents[digest]} (a copy): its labels would count twice; "
                             "give each file once")
        contents[digest] = given
    out = []
    for path in resolved:
        k = 1
        while k < len(path.parts) and any(o != path and o.parts[-k:] == path.parts[-k:] for o in resolved):
            k += 1
        out.append(str(Path(*path.parts[-k:])))
    return list(zip(out, contents))


#: [bytes] read at a time to hash a label file (an HDF5 file may be large).
_BLOCK = 1 << 20


def file_digest(path: Path) -> str:
    """sha256 of a file's bytes (a name of its own where it cannot be read: the reader says why, by name)."""
    import hashlib

    digest = hashlib.sha256()
    try:
        with path.open("rb") as f:  # hashlib.file_digest is Python 3.11's; the project runs on 3.10
            for block in iter(lambda: f.read(_BLOCK), b""):
                digest.update(block)
        return digest.hexdigest()
    except OSError:
        return f"unreadable:{path}"


def check_labelled(paths: Sequence[Path], *, poses: int | None, hand: str | None, trial: int, engine: str) -> str:
    """The files' one hand, or a one-line error before any work (and before ``grasp calibrate`` opens its
    database: a refused run leaves no database behind): no files, a file missing or not ACRONYM's, bad counts."""
    if not paths:
        raise InputError("no label files given")
    if poses is not None and poses < 1:
        raise InputError(f"--poses must be 0 (every pose) or a count of at least 1, got {poses}")
    if trial < 0:
        raise InputError(f"--trial must be >= 0, got {trial}")
    if engine not in TRIAL_GROUPS:
        raise InputError(f"--engine must be one of {', '.join(TRIAL_GROUPS)}; got '{engine}'")
    return file_hand(list(map(Path, paths)), hand)


def check_objects(paths: Sequence[Path], hand: str) -> None:
    """Refuse files of ``hand`` (:func:`check_labelled`'s) that are all of one object before any pose is closed
    (calibration's folds are grouped by object: refused after every pose was closed, minutes on real files); a
    file whose labels cannot be read is said first."""
    objects = {group(importer.read_for_rescoring(Path(p), hand)[1]) for p in paths
               if acronym.read_labels(Path(p)) is not None}
    if len(objects) < 2:
        raise InputError(f"calibration needs labelled grasps of at least 2 objects (folds grouped by object); "
                         f"the {len(paths)} file(s) given are all of {objects.pop()}: add another object's files")


def group(spec: ObjectSpec) -> str:
    """A labelled grasp's group, for folds grouped by object: its mesh file (two scales of one file are one
    object), or the built-in object's name."""
    return spec.source if spec.user_file else spec.name


def file_hand(paths: Sequence[Path], hand: str | None) -> str:
    """The one hand of every file, from its ``gripper/type`` (read before any pose is re-scored); ``hand``
    (``--hand``) only for files whose type names no known hand. A file whose type names another hand than
    ``hand``, or than most files, is refused by name: its labels are another hand's."""
    from planner.datasets.file_objects import HAND_ALIASES, hand_name
    from planner.specs.hands import hand_names

    of: dict[Path, str] = {}
    for path in paths:
        gripper = acronym.read_header(path).gripper
        named = HAND_ALIASES.get(gripper.lower(), gripper)
        if hand is not None and named in hand_names() and named != hand:
            raise InputError(f"{path}: gripper/type '{gripper}' is not --hand {hand}: its labels are the "
                             f"{named}'s; leave --hand out, or calibrate the {named}'s files alone")
        of[path] = hand or hand_name(path, gripper)
    counts = Counter(of.values())
    usual = max(counts, key=lambda h: (counts[h], -list(of.values()).index(h)))  # most files; a tie: the first
    odd = next((p for p, h in of.items() if h != usual), None)
    if odd is not None:
        others = [p.name for p, h in of.items() if h == usual]
        shown = ", ".join(others[:3]) + (", ..." if len(others) > 3 else "")
        raise InputError(f"{odd}: gripper/type '{acronym.read_header(odd).gripper}' is hand {of[odd]}, but the "
                         f"other files' hand is {usual} ({shown}): calibrate one hand at a time")
    return usual


def object_properties(spec: ObjectSpec) -> dict[str, float]:
    """The properties of :data:`~planner.calibration.logistic.DOMAIN` of the object ``spec`` makes (its mass and
    friction as the labelled file gives them; its density from the checked mesh's volume)."""
    from planner.calibration.logistic import properties
    from planner.geometry.solid import prepare

    return properties(prepare(spec))


#: The trial engines (``grasp validate --engine``) and the record group that stores each one's verdicts.
TRIAL_GROUPS = {"mujoco": "mujoco", "pybullet": "validation"}


def _tried(hand: HandSpec, spec: ObjectSpec, grasps: list[Grasp], k: int, seed: int, stem: str,
           engine: str) -> np.ndarray:
    """(len(grasps),) verdicts of a seeded sample of ``k`` of one file's closed grasps in ``engine``
    (1 held, 0 dropped; NaN: not in the sample)."""
    from planner.geometry.solid import prepare

    rows = sample_rows(len(grasps), k, seed + 1, stem)
    obj = prepare(spec)
    if engine == "mujoco":
        from planner.validation import mujoco_trial  # loads MuJoCo: only where asked for

        outcome = mujoco_trial.trials(hand, obj, [grasps[i] for i in rows])
    else:
        from planner.validation import shake

        outcome = shake.trials(hand, obj, [grasps[i] for i in rows])
    out = np.full(len(grasps), np.nan)
    out[rows] = [float(t.success) for t in outcome]
    return out
