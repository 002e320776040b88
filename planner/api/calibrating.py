"""Calibrating p_hold: :func:`calibrate` fits it to labelled grasp files
and stores it; :func:`report` writes the calibration report and
:func:`calibration_errors` gives its expected calibration errors.
"""

from __future__ import annotations

import contextlib
import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from planner.api.resolving import DEFAULT_DB
from planner.db.store import open_db, open_for_writing
from planner.errors import InputError
from planner.specs.inputs import check_output, check_seed, writing

if TYPE_CHECKING:
    from planner.calibration.fitting import Calibration
    from planner.record.grasp import Grasp


#: Suffixes of files ``grasp report --out`` does not write (``--out report.png`` made a folder of that name).
NOT_A_REPORT = (".png", ".jpg", ".jpeg", ".svg", ".pdf", ".md", ".txt", ".htm", ".json", ".csv")


def report(db_path: Path, out: Path) -> Path:
    """The calibration report of ``db_path``: ``out.html``, or a folder with
    ``report.md`` and PNGs (the reliability diagram of each hand's p_hold
    among them); returns the file written."""
    return report_and_errors(db_path, out)[0]


def report_and_errors(db_path: Path, out: Path) -> tuple[Path, list[str]]:
    """:func:`report` and :func:`calibration_errors` of ``db_path`` from one read of its p_hold section (its grasps
    an imported file labels, its trials, each hand's model): the file written and the lines."""
    from planner.present import reliability
    from planner.present import report as reporting

    suffix = Path(out).suffix.lower()
    if suffix in NOT_A_REPORT and not Path(out).is_dir():
        raise InputError(f"--out {out}: the report is an .html file or a folder (report.md and its PNGs in it), "
                         f"not a {suffix} file: give {Path(out).with_suffix('.html')} or a folder")
    out = check_output(Path(out), "--out", folder=suffix != ".html")
    found = reliability.read(Path(db_path))
    with writing(out, "--out"):
        path = reporting.write(Path(db_path), out, found)
    return path, reliability.ece_lines(found[0]) + reliability.file_lines(found[1])


def calibration_errors(db_path: Path) -> list[str]:
    """Per hand with a p_hold model: the expected calibration error of each of
    its reliability tables (held out on its labels; against stored trials; against the imported files' own
    labels); and per hand whose grasps an imported file labels, how p_hold and the score rank those labels."""
    from planner.present import reliability

    cals, files = reliability.read(Path(db_path))
    return reliability.ece_lines(cals) + reliability.file_lines(files)


def fitted_on(db_path: Path, hand: str, file: Path) -> bool:
    """Whether ``hand``'s p_hold model in ``db_path`` (the stored one, else the shipped one) was fitted on the
    labels of ``file`` (by its bytes' sha256 where the model records its files', else by its name): p_hold and the
    score against those labels are in-sample, no check of it."""
    from planner.calibration.labels import file_digest
    from planner.present import reliability

    with open_db(Path(db_path), create=False, readonly=True) as db:
        fitted = reliability.of_model(db.model_source(hand), db.model(hand))
    return fitted is not None and fitted.holds(file, file_digest(Path(file)) if fitted.hashes else None)


def in_sample_grasps(db_path: Path, hand: str, grasps: Sequence[Grasp]) -> int:
    """How many of ``grasps`` (``hand``'s, read from ``db_path``) carry the labels of a file ``hand``'s p_hold model
    there was fitted on (as :func:`fitted_on` matches it): their p_hold against those labels is no check of it."""
    return sum(in_sample(db_path, hand, grasps))


def in_sample(db_path: Path, hand: str, grasps: Sequence[Grasp]) -> tuple[bool, ...]:
    """Per grasp of ``grasps`` (``hand``'s, read from ``db_path``), whether it carries the labels of a file
    ``hand``'s p_hold model there was fitted on (:func:`in_sample_grasps`; ``best --json``'s ``in_sample``)."""
    from planner.present import reliability

    if not any(g.file_label is not None for g in grasps):
        return (False,) * len(grasps)
    with open_db(Path(db_path), create=False, readonly=True) as db:
        fitted = reliability.of_model(db.model_source(hand), db.model(hand))
        hashes = db.label_file_hashes() if fitted is not None and fitted.hashes else {}
    return reliability.in_sample_flags(grasps, fitted, hashes)


def calibrate(label_files: Sequence[Path], *, db_path: Path | None = DEFAULT_DB, poses: int | None = 200, seed: int = 0,
              folds: int = 5, hand: str | None = None, workers: int = 1, model_out: Path | None = None,
              plot: Path | None = None, progress: Callable[[Path, int, int], None] | None = None,
              trees: bool = True, trial: int = 0, engine: str = "mujoco") -> Calibration:
    """Fit p_hold (and so the ranking, by p_hold) to labelled grasp files in
    ACRONYM layout: a seeded sample of ``poses`` poses per file (0 or None: every pose) re-scored as
    ``import --rescore`` does, cross-validated over ``folds`` folds grouped by
    object. The model and its source are stored in ``db_path`` (None: not
    stored), where ``best``, exports and reports use it for its hand;
    ``model_out`` writes it as TOML (the form of the shipped default),
    ``plot`` the held-out reliability diagram as PNG; ``trees``: the model
    gets its interaction trees (False: the additive model alone); ``trial``:
    that many closed grasps per file tried in ``engine`` (``mujoco`` or
    ``pybullet``), and the model gets how that trial's verdict updates
    p_hold (:mod:`planner.calibration.update`)."""
    from planner.calibration.fitting import calibrate as fit_calibration
    from planner.calibration.labels import check_labelled, check_objects, label_names, labelled
    from planner.calibration.model import DEFAULT_TREES

    if plot is not None and Path(plot).suffix.lower() != ".png":
        raise InputError(f"{plot}: the reliability diagram is written as PNG; give a .png path")
    if folds < 2:
        raise InputError(f"--folds must be at least 2, got {folds}")
    check_seed(seed)
    if workers < 1:
        raise InputError(f"--workers must be at least 1, got {workers}")
    paths = [Path(p) for p in label_files]
    for path, option in ((model_out, "--model-out"), (plot, "--plot")):
        if path is not None:
            check_output(Path(path), option)
    poses = poses or None  # 0: every pose, as `--poses 0` and the error for a negative count say
    check_objects(paths, check_labelled(paths, poses=poses, hand=hand, trial=trial, engine=engine))
    # the database is opened (and locked) first: one that cannot take the model says so before the fit, not after
    with open_for_writing(Path(db_path)) if db_path is not None else contextlib.nullcontext() as db:
        data = labelled(paths, poses=poses, seed=seed, hand=hand, workers=workers, progress=progress, trial=trial,
                        engine=engine)
        source = json.dumps({"command": "grasp calibrate", "labels": label_names(paths),
                             "poses_per_file": poses, "seed": seed, "folds": folds, "grasps": len(data.labels),
                             "objects": len(set(data.groups)), "rejected": data.rejected, "trees": trees,
                             **({"trial": trial, "engine": engine} if trial else {})}, sort_keys=True)
        result = fit_calibration(data, folds=folds, source=source, trees=DEFAULT_TREES if trees else None)
        if db is not None:
            db.write_model(result.model, source, db.rule())
    if model_out is not None:
        with writing(Path(model_out), "--model-out"):
            Path(model_out).parent.mkdir(parents=True, exist_ok=True)  # check_output let a new folder through
            Path(model_out).write_text(result.model.to_toml(), encoding="utf-8")
    if plot is not None:
        from planner.calibration.plot import reliability_png

        png = reliability_png([("held out (grouped CV)", result.reliability)],
                              f"p_hold, {result.model.hand}: {len(data.labels)} labelled grasps")
        with writing(Path(plot), "--plot"):
            Path(plot).parent.mkdir(parents=True, exist_ok=True)
            Path(plot).write_bytes(png)
    return result


def shipped_figures(hand: str) -> dict[str, float]:
    """The held-out figures of the model shipped for ``hand`` (``calibration/<hand>.toml``, fitted on ACRONYM's dev
    set): what a model ``calibrate`` stores replaces for that database's grasps; {} where none is shipped (or
    ``$GRASP_SHIPPED_MODELS`` is "0")."""
    from planner.calibration.logistic import default_model

    model = default_model(hand)
    return {} if model is None else dict(model.figures)
