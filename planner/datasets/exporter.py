"""Export: the grasp database as files that learning pipelines read.

Formats (one module each, registered in :mod:`planner.datasets.registry`):

- ``acronym``: HDF5 per (object, hand), ACRONYM's layout plus this
  project's extras (:mod:`planner.datasets.acronym`);
- ``graspgen``: the same content as JSON per (object, hand), in GraspGen's
  per-gripper dataset layout (:mod:`planner.datasets.graspgen`);
- ``dexgraspnet``: ``.npy`` list of ``{scale, qpos}`` dicts per (object,
  hand), in DexGraspNet's layout (:mod:`planner.datasets.dexgraspnet`);
- ``parquet`` / ``csv``: one flat table of every grasp
  (:mod:`planner.datasets.table`, whose ``COLUMNS_DOC`` documents the columns).

Every export folder is self-contained: the mesh of every exported object is
written first, as ``DIR/meshes/<object>.obj`` in metres
(:mod:`planner.datasets.meshes`), and every file names its mesh by that
path relative to ``DIR`` with scale 1, so the folder can be copied to
another machine. Each per-pair module says where its files go
(``relative_path``). Exports stream: grasps are read from the database in
batches of :data:`BATCH_SIZE` (rank order within a pair) and written as they
come, so no exporter holds all grasps of a database in memory; every file is
written under a temporary name and renamed when complete.
"""

from __future__ import annotations

import contextlib
import json
import logging
import math
import os
import shlex
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import closing
from dataclasses import dataclass, field, replace
from itertools import chain
from pathlib import Path, PurePosixPath
from typing import TYPE_CHECKING

from planner.datasets import formats
from planner.datasets.columns import Stream
from planner.datasets.labels import BEST, FILE_LABEL, FORCE_CLOSURE, P_HOLD, P_HOLD_TRIAL, TRIAL, check, has_label
from planner.datasets.meshes import ExportedObject, mesh_stem, write_meshes
from planner.datasets.registry import PairWriter, TableWriter
from planner.db.store import Database, open_db
from planner.errors import InputError
from planner.record.grasp import Grasp
from planner.specs.hands import HandSpec, load_hand

if TYPE_CHECKING:
    from planner.calibration.logistic import LogisticModel
    from planner.db.diverse import Spacing

log = logging.getLogger(__name__)

#: Grasps per database read: about 10 MB of decoded records.
BATCH_SIZE = 5000

#: Every format with a writer (:mod:`planner.datasets.registry`).
FORMATS = formats.EXPORT_FORMATS


@dataclass(frozen=True)
class Selection:
    """Which grasps to export (empty tuples: all)."""

    objects: tuple[str, ...] = ()
    hands: tuple[str, ...] = ()
    min_epsilon: float | None = None  # keep epsilon >= this
    top: int | None = None  # keep rank <= this per (object, hand)
    spacing: Spacing | None = None  # with top: the top best grasps this far apart (planner.db.diverse)
    label: str = BEST  # the success label written (planner.datasets.labels); trial / p_hold: only grasps with one

    def __post_init__(self) -> None:
        if self.top is not None and self.top < 1:
            raise InputError(f"--top must be at least 1, got {self.top}")
        if self.spacing is not None and self.top is None:
            raise InputError("--diverse needs --top K: how many diverse grasps to export per object and hand")
        if self.min_epsilon is not None and not math.isfinite(self.min_epsilon):
            raise InputError(f"--min-epsilon must be a finite number, got {self.min_epsilon}")

    def pairs(self, db: Database) -> list[tuple[str, str]]:
        """(object, hand) pairs to export; a named object or hand without grasps is an error."""
        found = db.pairs()
        for kind, wanted, index in (("object", self.objects, 0), ("hand", self.hands, 1)):
            known = sorted({p[index] for p in found})
            for name in wanted:
                if name not in known:
                    raise InputError(f"{db.path}: no grasps of {kind} '{name}'; {kind}s with grasps: "
                                     f"{', '.join(known) or '(none)'}")
        return [p for p in found if (not self.objects or p[0] in self.objects)
                and (not self.hands or p[1] in self.hands)]

    def batches(self, db: Database, obj: str, hand: str) -> Iterator[list[Grasp]]:
        if self.spacing is None:
            found = db.grasp_batches(obj, hand, min_epsilon=self.min_epsilon, top=self.top, size=BATCH_SIZE)
        else:
            found = self._diverse(db, obj, hand)
        if self.label in (BEST, FORCE_CLOSURE):
            return found
        return (kept for batch in found if (kept := [g for g in batch if has_label(self.label, g)]))

    def _diverse(self, db: Database, obj: str, hand: str) -> Iterator[list[Grasp]]:
        """One batch: the ``top`` best diverse grasps (at most ``top``, so small)."""
        from planner.db.diverse import diverse

        spec = load_hand(hand)
        with closing(db.grasp_batches(obj, hand, min_epsilon=self.min_epsilon, size=BATCH_SIZE)) as batches:
            kept = diverse((g for b in batches for g in b if g.rank), self.top or 0, self.spacing,  # type: ignore[arg-type]
                           spec.tcp, spec.approach, spec.roll_symmetry)
        if kept:
            yield kept


@dataclass
class ExportSummary:
    """What an export wrote."""

    format: str
    files: list[Path] = field(default_factory=list)  # grasp files
    meshes: list[Path] = field(default_factory=list)  # DIR/meshes/<object>.obj, each followed by the format's copies
    grasps: int = 0
    seconds: float = 0.0
    notes: list[str] = field(default_factory=list)  # what a reader of the labels should know
    counts: list[int] = field(default_factory=list)  # grasps of each of ``files``
    manifest: Path | None = None  # DIR/export-<format>.json, written last (:data:`MANIFEST`)

    def to_json(self) -> dict:
        return {"format": self.format, "files": [str(p) for p in self.files],
                "meshes": [str(p) for p in self.meshes], "grasps": self.grasps, "seconds": round(self.seconds, 3),
                "notes": self.notes, "manifest": None if self.manifest is None else str(self.manifest)}


#: The export's manifest in DIR, one per format: moved aside before the export writes anything, written (atomically)
#: after its last file, so that a folder holding it holds that export whole (a killed or failed export leaves none):
#: what was exported, from which database, with which selection and labels, and each file with its grasps, bytes and
#: sha256 (hex: an earlier export's file is still its own only where its content is).
#: Its ``earlier`` lists the earlier exports of the format into DIR whose files are still there and this one did not
#: write again (each such export as its own record, with those files only; none: []).
MANIFEST = "export-{format}.json"
#: The manifest before, renamed out of the way while an export writes (removed once its own is written): a killed
#: or failed export, then another, lost every earlier export from ``earlier`` (the box's file there, unlisted).
PREVIOUS = ".export-{format}.previous.json"


def _earlier(out_dir: Path, fmt: str) -> list[dict]:
    """The records of the exports of ``fmt`` the manifest in ``out_dir`` describes (itself and its ``earlier``), or
    the one a stopped export moved aside (:data:`PREVIOUS`), read before a new export moves it aside (``grasp
    export --object box`` then ``--object mug`` into one folder: the second manifest described only the mug,
    beside the box's file)."""
    manifest, previous = out_dir / MANIFEST.format(format=fmt), out_dir / PREVIOUS.format(format=fmt)
    try:
        old = json.loads((manifest if manifest.is_file() else previous).read_text(encoding="utf-8"))
    except (OSError, ValueError):  # none, or not one this planner wrote whole: nothing to carry over
        return []
    if not isinstance(old, dict) or not isinstance(old.get("files"), list):
        return []
    listed = old.pop("earlier", [])
    earlier = [r for r in listed if isinstance(r, dict) and isinstance(r.get("files"), list)] \
        if isinstance(listed, list) else []
    return [*earlier, old]


def _listed(f: object) -> bool:
    """A file entry as :func:`_manifest` writes it: a path inside the folder, its grasps and bytes (an edited or
    damaged manifest's "earlier": null, "grasps": "many", a path outside the folder stopped the new export at
    its end with an internal error, its files written and no manifest; or listed /etc/passwd as exported)."""
    if not (isinstance(f, dict) and isinstance(f.get("path"), str) and type(f.get("grasps")) is int
            and type(f.get("bytes")) is int):
        return False
    path = PurePosixPath(f["path"])
    return not path.is_absolute() and ".." not in path.parts


def _sha256(path: Path) -> str:
    """The sha256 of a file's bytes, hex."""
    import hashlib

    digest = hashlib.sha256()
    with path.open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _as_it_was(f: dict, out_dir: Path) -> bool:
    """Whether a listed file is in ``out_dir`` as its export wrote it: its ``sha256`` (a file of the same size
    written over it, another object's export of the same length, matched by size alone), read again only where
    its modification time is not the one recorded (``mtime_ns``, as ``git status`` and ``make`` trust it: each
    export hashed every earlier export's files again, gigabytes of a dataset built object by object); a
    manifest written before the hash was stored: its ``bytes``."""
    path = out_dir / f["path"]
    if not path.is_file() or path.stat().st_size != f["bytes"]:
        return False
    if "sha256" not in f or f.get("mtime_ns") == path.stat().st_mtime_ns:
        return True
    return f["sha256"] == _sha256(path)


def _still_there(records: list[dict], out_dir: Path, written: set[str]) -> list[dict]:
    """``records`` with only the files still in ``out_dir`` as they were and not written again (``written``)."""
    kept = []
    for r in records:
        files = [{**f, "mtime_ns": (out_dir / f["path"]).stat().st_mtime_ns} if "sha256" in f else f  # hashed once
                 for f in r["files"] if _listed(f) and f["path"] not in written and _as_it_was(f, out_dir)]
        if files:
            kept.append({**r, "files": files, "grasps": sum(f["grasps"] for f in files)})
    return kept


def _manifest(summary: ExportSummary, out_dir: Path, db_path: Path, sel: Selection, earlier: list[dict]) -> Path:
    from planner import assets
    from planner.db.writing import now_text

    rel = lambda p: p.relative_to(out_dir).as_posix()  # noqa: E731
    record = {"format": summary.format, "complete": True, "finished_at": now_text(),
              "database": str(Path(db_path).resolve()), "grasps": summary.grasps,
              "selection": {"objects": list(sel.objects), "hands": list(sel.hands), "top": sel.top,
                            "min_epsilon": sel.min_epsilon, "label": sel.label,
                            "diverse": None if sel.spacing is None else {"translation": sel.spacing.translation,
                                                                         "rotation": sel.spacing.rotation}},
              "files": [{"path": rel(p), "grasps": n, "bytes": p.stat().st_size, "sha256": _sha256(p),
                         "mtime_ns": p.stat().st_mtime_ns} for p, n in zip(summary.files, summary.counts)],
              "meshes": [rel(p) for p in summary.meshes], "notes": summary.notes}
    record["earlier"] = _still_there(earlier, out_dir, {f["path"] for f in record["files"]})
    path = out_dir / MANIFEST.format(format=summary.format)
    assets.atomic_write(path, (json.dumps(record, indent=2) + "\n").encode())
    (out_dir / PREVIOUS.format(format=summary.format)).unlink(missing_ok=True)
    return path


def export(db_path: Path, fmt: str, out_dir: Path, *, objects: Sequence[str] = (), hands: Sequence[str] = (),
           min_epsilon: float | None = None, top: int | None = None, spacing: Spacing | None = None,
           label: str = BEST, progress: Callable[[Path, int], None] | None = None) -> ExportSummary:
    """Export the selected grasps of ``db_path`` as ``fmt`` into ``out_dir``
    (created if missing). ``top``: rank <= top per (object, hand);
    ``min_epsilon``: epsilon >= it. ``progress(file, grasps)`` after each file."""
    writing: list[Path] = []  # the files this export writes, each under its name + ".tmp" until whole
    made = _missing_root(Path(out_dir))
    try:
        return _export(db_path, fmt, out_dir, objects, hands, min_epsilon, top, spacing, label, progress, writing)
    except BaseException as exc:  # a full disk, Ctrl-C: no file of this export is left half-written, under any name
        for path in writing:
            with contextlib.suppress(OSError):
                path.with_name(path.name + ".tmp").unlink(missing_ok=True)
        if made is not None:  # a refusal (a name clash) after the folder was made: no empty folder left behind
            _remove_empty(made)
        if isinstance(exc, OSError):
            raise InputError(f"{out_dir}: cannot write the export ({exc.strerror or exc}): no file under its final "
                             "name is partial, unfinished ones were removed; free space or choose another --out") \
                from exc
        raise


def _export(db_path: Path, fmt: str, out_dir: Path, objects: Sequence[str], hands: Sequence[str],
            min_epsilon: float | None, top: int | None, spacing: Spacing | None, label: str,
            progress: Callable[[Path, int], None] | None, writing: list[Path]) -> ExportSummary:
    writer = formats.writer(fmt)
    sel = Selection(tuple(objects), tuple(hands), min_epsilon, top, spacing, check(label))
    summary = ExportSummary(fmt)
    start = time.perf_counter()
    with open_db(Path(db_path), create=False, readonly=True) as db:
        pairs = sel.pairs(db)
        if not pairs:  # nothing to filter: every sweep kept none (a named object or hand without grasps: above)
            raise InputError(f"{db_path}: no grasps stored: nothing written; `grasp best OBJECT --hand HAND --db "
                             f"{shlex.quote(str(db_path))}` says why an object has none")
        specs = {h: load_hand(h) for h in sorted({h for _, h in pairs})}  # unknown hands fail up front
        models = {h: db.model(h) for h in specs}  # read once: a model with trees is ~0.3 MB of JSON
        if sel.label == BEST:
            summary.notes += [f"hand '{h}' has no calibrated p_hold model: its grasps that neither an imported file "
                              "labels (label_from file_label) nor a trial tried are labelled by the force-closure flag "
                              "(label_from force_closure), which is not a success label; "
                              "`grasp validate --all --force-closure` gives each a trial's verdict"
                              for h, model in models.items() if model is None]
        if isinstance(writer, TableWriter) and writer.notes is not None:
            summary.notes += writer.notes(pairs)
        if not any(_has_one(sel.batches(db, o, h)) for o, h in pairs):
            raise InputError(f"{db_path}: no grasp of the {len(pairs)} (object, hand) pairs selected passes the "
                             f"filters (--top, --min-epsilon, --label): nothing written{_why_none(sel, models)}")
        out_dir = _out_dir(Path(out_dir))
        copies = writer.mesh_copies if isinstance(writer, PairWriter) else ()
        exported = {name: replace(o, label=sel.label)  # a mesh another database put there is refused first
                    for name, o in write_meshes(db, sorted({o for o, _ in pairs}), out_dir, copies).items()}
        earlier = _earlier(out_dir, fmt)
        if (out_dir / MANIFEST.format(format=fmt)).is_file():  # no stale "complete" over new files
            os.replace(out_dir / MANIFEST.format(format=fmt), out_dir / PREVIOUS.format(format=fmt))
        summary.meshes = [out_dir / path for name, o in exported.items()  # the copies a format reads too
                          for path in (o.file, *(c.format(stem=mesh_stem(name)) for c in copies))]
        if isinstance(writer, TableWriter):
            path = out_dir / writer.file
            writing.append(path)
            tmp = path.with_name(path.name + ".tmp")
            streams = (Stream(_for_hand(models[h], exported[o]), h, sel.batches(db, o, h)) for o, h in pairs)
            summary.grasps = writer.write(tmp, streams)
            os.replace(tmp, path)
            summary.files.append(path)
            summary.counts.append(summary.grasps)
            if progress:
                progress(path, summary.grasps)
        else:
            for obj, hand in pairs:
                path = out_dir / writer.relative_path(mesh_stem(obj), hand)
                writing.append(path)
                count = _write_pair(db, writer, path, _for_hand(models[hand], exported[obj]), specs[hand], sel)
                if count:
                    summary.files.append(path)
                    summary.counts.append(count)
                    summary.grasps += count
                    if progress:
                        progress(path, count)
            if writer.finish is not None:
                writer.finish(out_dir, sorted(specs))
        summary.manifest = _manifest(summary, out_dir, Path(db_path), sel, earlier)
    summary.seconds = time.perf_counter() - start
    log.info("exported %d grasps as %s to %s in %.1f s", summary.grasps, fmt, out_dir, summary.seconds)
    return summary


def _why_none(sel: Selection, models: dict[str, LogisticModel | None]) -> str:
    """What a label that only some grasps have needs (a Barrett's --label p_hold said only 'the filters')."""
    lacking = sorted(h for h, m in models.items() if m is None)
    if sel.label in (P_HOLD, P_HOLD_TRIAL) and lacking:
        return (f"; --label {sel.label} takes grasps with a p_hold, and hand {', '.join(lacking)} has no p_hold "
                "model (`grasp calibrate` fits one)")
    if sel.label in (TRIAL, P_HOLD_TRIAL):
        return f"; --label {sel.label} takes only grasps a trial tried (`grasp validate`)"
    if sel.label == FILE_LABEL:
        return f"; --label {sel.label} takes only grasps imported from a labelled file (`grasp import`)"
    return ""


def _for_hand(model: LogisticModel | None, obj: ExportedObject) -> ExportedObject:
    """The object as written with a hand's grasps: where it lies outside that hand's p_hold ``model``'s domain."""
    return obj if model is None else replace(obj, p_hold_outside=tuple(model.outside(obj.row.properties())))


def _write_pair(db: Database, writer: PairWriter, path: Path, obj: ExportedObject, hand: HandSpec,
                sel: Selection) -> int:
    """Write one (object, hand) file; none when the filters leave no grasp."""
    batches = sel.batches(db, obj.name, hand.name)
    first = next(batches, None)
    if first is None:
        return 0
    path.parent.mkdir(parents=True, exist_ok=True)
    return int(writer.write(path, obj, hand, chain([first], batches)))


def _has_one(batches: Iterator[list]) -> bool:
    """Whether ``batches`` (closed here) hold a grasp."""
    try:
        return next(batches, None) is not None
    finally:
        close = getattr(batches, "close", None)
        if close is not None:
            close()


def _out_dir(path: Path) -> Path:
    if path.exists() and not path.is_dir():
        raise InputError(f"{path}: --out must be a folder, but it is a file")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"{path}: cannot create the output folder ({exc.strerror})") from exc
    return path


def _missing_root(path: Path) -> Path | None:
    """The outermost folder of ``path`` that does not exist yet, which an export creates (None: ``path`` exists)."""
    missing = None
    for folder in (path, *path.parents):
        if folder.exists():
            break
        missing = folder
    return missing


def _remove_empty(top: Path) -> None:
    """Remove ``top``, a folder this export created, and every folder under it, where nothing was written."""
    for folder, _, _ in os.walk(top, topdown=False):
        with contextlib.suppress(OSError):  # not empty: something was written there, which stays
            os.rmdir(folder)
