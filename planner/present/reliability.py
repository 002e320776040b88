"""``grasp report``'s p_hold section: each hand's p_hold model against what labels its grasps.

Three sets of labels, each its own reliability table (predicted p_hold vs observed success per decile) with its
expected calibration error, drawn as one diagram per hand (``reliability_<hand>.png``):

* the model's held-out predictions on the labels it was fitted on (its source: the shipped model's ACRONYM dev
  set, or ``grasp calibrate``'s files);
* the stored trials of this project (MuJoCo's, else PyBullet's: :func:`engines` says whose);
* the labels of the files the grasps were imported from (``grasp import``: ACRONYM's
  ``grasps/qualities/flex/object_in_gripper``, FleX's verdicts in ACRONYM's own files, a user's outcomes in
  theirs), named by their source, with the ROC AUC of p_hold and of the analytic score against them. These are
  the file's, not a trial of this project's: they are never mixed with the trials.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from planner.calibration.metrics import Reliability, reliability, roc_auc
from planner.db.store import open_db
from planner.record.grasp import Grasp

if TYPE_CHECKING:
    from planner.calibration.logistic import LogisticModel


@dataclass(frozen=True)
class FileLabels:
    """The grasps of one hand an imported file labels, as the report compares them.

    count, held: how many, and how many of them the files label held; sources: the distinct
    :attr:`~planner.record.grasp.FileLabel.source` of their labels (a file and dataset each), sorted;
    p_hold: the reliability table of p_hold against the labels (None: no model applies to the hand);
    auc_p_hold, auc_score: ROC AUC of p_hold and of the analytic score (the ranking rule without trials)
    against the labels (NaN: one class only, or not computed); in_sample: how many of them are of a file whose
    labels the hand's p_hold model was fitted on (``grasp calibrate`` of the imported file): not a check of it.
    """

    count: int
    held: int
    sources: tuple[str, ...]
    p_hold: Reliability | None
    auc_p_hold: float
    auc_score: float
    in_sample: int = 0

    @property
    def named(self) -> str:
        """The labels' source as said: the one source, else how many and the first."""
        first = self.sources[0] if self.sources else "unknown"
        return first if len(self.sources) <= 1 else f"{len(self.sources)} sources: {first}, ..."


def file_labels(grasps: Sequence[Grasp], scores: np.ndarray, fitted: FittedOn | None = None,
                hashes: Mapping[int, str] | None = None) -> FileLabels:
    """:class:`FileLabels` of ``grasps`` (each with a file label) and their analytic ``scores`` (n,); ``fitted``:
    the files the hand's p_hold model was fitted on (:func:`fitted_on`); ``hashes``: unit id -> the sha256 of the
    file whose labels the unit's grasps carry (:meth:`~planner.db.units.UnitReads.label_file_hashes`)."""
    y = np.array([g.file_label.success for g in grasps], float)  # type: ignore[union-attr]
    p = np.array([math.nan if g.p_hold is None else g.p_hold for g in grasps], float)
    modelled = bool(np.isfinite(p).any())
    in_sample = count_in_sample(grasps, fitted, hashes) if modelled else 0
    return FileLabels(len(grasps), int(y.sum()), tuple(sorted({g.file_label.source for g in grasps})),  # type: ignore[union-attr]
                      reliability(y, p) if modelled else None, roc_auc(y, p) if modelled else math.nan,
                      roc_auc(y, np.asarray(scores, float)), in_sample)


def count_in_sample(grasps: Sequence[Grasp], fitted: FittedOn | None, hashes: Mapping[int, str] | None) -> int:
    """How many of ``grasps`` carry the labels of a file ``fitted`` holds (:func:`file_labels`'s arguments)."""
    return sum(in_sample_flags(grasps, fitted, hashes))


def in_sample_flags(grasps: Sequence[Grasp], fitted: FittedOn | None,
                    hashes: Mapping[int, str] | None) -> tuple[bool, ...]:
    """Per grasp of ``grasps``, whether it carries the labels of a file ``fitted`` holds (:func:`file_labels`'s
    arguments; ``fitted`` None: no model, none is)."""
    if fitted is None:
        return (False,) * len(grasps)
    hashes = hashes or {}
    return tuple(g.file_label is not None and fitted.holds(_file_name(g.file_label.source),
                                                           None if g.unit_id is None else hashes.get(g.unit_id))
                 for g in grasps)


@dataclass(frozen=True)
class FittedOn:
    """The label files a p_hold model was fitted on, as an imported file is matched against them.

    names: their names; hashes: the sha256 (hex) of each one's bytes (empty: the model records none, one made
    before 2026-12-07 evening, and a file is matched by its name alone: another file of that name is taken for it)."""

    names: frozenset[str] = frozenset()
    hashes: frozenset[str] = frozenset()

    def holds(self, file: str | Path, sha256: str | None = None) -> bool:
        """Whether the labels of ``file`` (a path or name; ``sha256``: of its bytes, None: not known) are among
        them: by content where the model records hashes (a copy under another name is one of them; another file
        of one of their names is not), else by name (``crate`` and ``crate.h5`` are one file: a benchmark fits on
        stems)."""
        if self.hashes:
            return sha256 is not None and sha256.lower() in self.hashes
        return _key(Path(file).name) in {_key(name) for name in self.names}


def fitted_on(source: str, labels: Sequence[str] = (), hashes: Sequence[str] = ()) -> FittedOn:
    """The label files a model was fitted on: its ``labels`` and ``hashes`` (:attr:`LogisticModel.labels`,
    :attr:`LogisticModel.label_hashes`: the shipped model's dev-set files, ``grasp calibrate``'s) and the names a
    source stored by ``grasp calibrate`` gives (its ``labels``, each as
    :func:`planner.calibration.labels.label_names` spelt it; a model stored before the model kept them)."""
    try:
        named = json.loads(source).get("labels", [])
    except (ValueError, AttributeError):
        named = []
    return FittedOn(frozenset(Path(str(name)).name for name in [*named, *labels]),
                    frozenset(str(h).lower() for h in hashes))


def of_model(source: str, model: LogisticModel | None) -> FittedOn | None:
    """:func:`fitted_on` of a hand's model and its stored source; None: the hand has no model."""
    return None if model is None else fitted_on(source, model.labels, model.label_hashes)


def in_sample(fitted: FittedOn, file: str | Path, sha256: str | None = None) -> bool:
    """Whether the labels of ``file`` are among those a model fitted on ``fitted`` was fitted on
    (:meth:`FittedOn.holds`)."""
    return fitted.holds(file, sha256)


def _key(name: str) -> str:
    return name[:-3] if name.lower().endswith(".h5") else name


def _file_name(source: str) -> str:
    """The file of a :attr:`~planner.record.grasp.FileLabel.source` (``crate.h5 grasps/qualities/flex/...``)."""
    return source.rpartition(" grasps/")[0] or source


@dataclass(frozen=True)
class HandCalibration:
    """A hand's p_hold model as the report shows it: where it came from, its
    held-out reliability table (None: not recorded) and p_hold against the
    stored trials (None: no trial of a grasp with p_hold); outside: per
    object of the hand outside the labelled objects the model was fitted on,
    how (:meth:`~planner.calibration.logistic.LogisticModel.outside`);
    held_out_ece: the 95% interval over objects of the held-out ECE that
    the fit recorded (``ece_lo``, ``ece_hi`` of its figures; None: a fit
    that predates them); files: its grasps' imported files' own labels (None: none has one)."""

    hand: str
    source: str
    held_out: Reliability | None
    trials: Reliability | None
    outside: dict[str, list[str]] = field(default_factory=dict)
    held_out_ece: tuple[float, float] | None = None

    engines: str = ""  # whose verdicts ``trials`` holds (:func:`engines`)
    files: FileLabels | None = None

    def curves(self) -> list[tuple[str, Reliability]]:
        files = None if self.files is None else self.files.p_hold
        return [(label, r) for label, r in (("held out on its labels: the model's source", self.held_out),
                                            (f"trials: {self.engines}", self.trials),
                                            (f"the imported files' own labels ({self._files_named()})", files))
                if r is not None]

    def _files_named(self) -> str:
        if self.files is None:
            return ""
        f = self.files
        return f.named + (f"; in-sample: {f.in_sample} of them of the files p_hold was fitted on" if f.in_sample
                          else "")


def labelled(db_path: Path) -> dict[str, FileLabels]:
    """Per hand whose grasps an imported file labels (``grasp import``), how p_hold and the score meet the labels."""
    return read(db_path)[1]


def calibration(db_path: Path) -> list[HandCalibration]:
    """Every hand of the database that has a p_hold model: a hand with grasps (its stored or shipped model), or
    one ``grasp calibrate`` stored a model for (a database with no grasps yet: its held-out figures)."""
    return read(db_path)[0]


def read(db_path: Path) -> tuple[list[HandCalibration], dict[str, FileLabels]]:
    """:func:`calibration` and :func:`labelled` of ``db_path`` from one read: its grasps an imported file labels,
    its tried grasps and each hand's model, each read once."""
    from planner.present.report import untried_analytic

    with open_db(Path(db_path), create=False, readonly=True) as db:
        marked, rule, tried_all = db.validated(file_labels=True), db.rule(), db.validated()
        modelled = sorted({h for _, h in db.pairs()} | set(db.calibrated_hands()))
        hands = sorted(set(modelled) | {g.hand for g in marked})
        models, sources = {h: db.model(h) for h in hands}, {h: db.model_source(h) for h in hands}
        hashes = db.label_file_hashes() if marked else {}
        files = {hand: file_labels(mine, untried_analytic(rule, mine), of_model(sources[hand], models[hand]), hashes)
            for hand in sorted({g.hand for g in marked}) for mine in [[g for g in marked if g.hand == hand]]}
        out = []
        for hand in modelled:
            model = models[hand]
            if model is None:
                continue
            tried = [g for g in tried_all if g.hand == hand and g.p_hold is not None]
            trials = reliability(np.array([g.trial.success for g in tried], float),  # type: ignore[union-attr]
                                 np.array([g.p_hold for g in tried], float)) if tried else None
            rows = {name: db.object_row(name) for name in db.objects_for(hand)}
            outside = {name: model.outside(row.properties()) for name, row in rows.items() if row is not None}
            lo, hi = (model.figures.get(f"ece_{end}", math.nan) for end in ("lo", "hi"))
            source = sources[hand]
            source = f"{source}: {model.source}" if source == "shipped" and model.source else source
            out.append(HandCalibration(hand, source, model.held_out, trials,
                                       {name: why for name, why in outside.items() if why},
                                       (lo, hi) if math.isfinite(lo) and math.isfinite(hi) else None,
                                       engines(tried), files.get(hand)))
    return out, files


def engines(grasps: Sequence[Grasp]) -> str:
    """Whose verdicts label ``grasps`` (each its :attr:`Grasp.trial`): ``MuJoCo 120, PyBullet 298``; an engine that
    labels none is left out (a legend's "PyBullet 0" read as a trial that held none)."""
    mujoco = sum(g.mujoco is not None for g in grasps)
    return ", ".join(f"{name} {n}" for name, n in (("MuJoCo", mujoco), ("PyBullet", len(grasps) - mujoco)) if n) + (
        " (MuJoCo's verdict where both tried a grasp)" if any(g.mujoco and g.validation for g in grasps) else "")


def ece_lines(cals: list[HandCalibration]) -> list[str]:
    """One line per hand and reliability table: its expected calibration error."""
    lines = []
    for c in cals:
        for label, r in c.curves():
            lines.append(f"{c.hand}: ECE of p_hold ({label}, {int(r.count.sum())} grasps) = {r.ece:.4f}"
                         + (_interval(c.held_out_ece) if r is c.held_out else ""))
        lines += [f"{c.hand}: p_hold of {name} is extrapolated, outside the labelled objects it was fitted on: "
                  f"{'; '.join(why)}" for name, why in sorted(c.outside.items())]
    return lines


def file_lines(files: dict[str, FileLabels]) -> list[str]:
    """One line per hand whose grasps an imported file labels: how many, from where, and how p_hold (where a
    model applies) and the analytic score rank them."""
    lines = []
    for hand, f in sorted(files.items()):
        aucs = "; ".join(f"ROC AUC of {name} against them {auc:.3f}" for name, auc in
                         (("p_hold", f.auc_p_hold), ("the analytic score", f.auc_score)) if math.isfinite(auc))
        lines.append(f"{hand}: the imported files' own labels ({f.named}; the files', not a trial of this project's): "
                     f"{f.count} grasps, {f.held} held, {f.count - f.held} dropped"
                     + (f"; {aucs}" if aucs else "; no ROC AUC without both outcomes") + _in_sample(f))
    return lines


def _in_sample(f: FileLabels) -> str:
    """Said where p_hold was fitted on some of these labels: its figures against them are no check of it."""
    return (f"; in-sample: the p_hold model was fitted on the labels of the files of {f.in_sample} of these "
            f"{f.count} grasps, so p_hold's figures (and the score's, which ranks by p_hold) against them are no "
            "check of it" if f.in_sample else "")


def _interval(ece: tuple[float, float] | None) -> str:
    if ece is None:
        return " (no interval: the model's fit predates them; `grasp calibrate` records one)"
    return f" [{ece[0]:.4f}, {ece[1]:.4f}] (95% over objects: a bootstrap drawing the labelled objects)"


def reliability_png(c: HandCalibration) -> bytes:
    """The hand's reliability diagram (every table of :meth:`HandCalibration.curves`) as PNG."""
    from planner.calibration.plot import reliability_png as png

    return png(c.curves(), f"p_hold of the {c.hand}: predicted vs observed success")
