"""A foreign labelled file's labels (ACRONYM's ``flex/object_in_gripper``) are kept on import: stored beside the
re-scored grasps, shown by ``grasp best``, exported again (as the label and as ``file_label_*``) and read back."""

from __future__ import annotations

import shutil
import sqlite3
from pathlib import Path

import h5py
import numpy as np
import pandas as pd
import pytest
from helpers import grasp, one_line_error

from tests.datasets.support import export
from tests.datasets.test_importer import foreign_file


def _labelled(db: Path, tmp_path: Path) -> tuple[Path, np.ndarray]:
    """A foreign file of the box's force-closure grasps, labelled held and dropped in turn."""
    foreign, _ = foreign_file(db, tmp_path, "box", "crate")
    with h5py.File(foreign, "r+") as f:
        key = "grasps/qualities/flex/object_in_gripper"
        labels = np.arange(len(f[key])) % 2
        f[key][...] = labels
    return foreign, labels


def _stored(db: Path) -> dict[int, tuple[int, str]]:
    with sqlite3.connect(db) as conn:
        return {c: (s, src) for c, s, src in conn.execute(
            "SELECT g.candidate, l.success, l.source FROM grasps g JOIN file_labels l ON l.grasp_id = g.id")}


def test_an_imported_files_labels_are_stored_shown_exported_and_read_back(db: Path, tmp_path: Path) -> None:
    """They were dropped: the grasps came back re-scored, the file's labels nowhere."""
    foreign, labels = _labelled(db, tmp_path)
    first = tmp_path / "first.db"
    code, out, err = grasp("import", str(foreign), "--db", str(first))
    assert code == 0, err
    stored = _stored(first)
    held = sum(s for s, _ in stored.values())
    assert f"the file's labels kept: {held} held, {len(stored) - held} dropped" in out, out
    with sqlite3.connect(first) as conn:
        kept = [c for (c,) in conn.execute("SELECT candidate FROM grasps")]
    assert kept and sorted(stored) == sorted(kept)  # every re-scored pose with its own row's label
    assert all(s == labels[c] and src == "crate.h5 grasps/qualities/flex/object_in_gripper"
               for c, (s, src) in stored.items())
    code, out, err = grasp("best", "crate", "--hand", "panda", "--db", str(first), "--top", "2")
    assert code == 0, err
    said = [line for line in out.splitlines() if "label of the file it was imported from" in line]
    assert len(said) == 2 and all("crate.h5 grasps/qualities/flex/object_in_gripper" in s for s in said), out
    code, _, err = grasp("export", "--db", str(first), "--format", "acronym", "--out", str(tmp_path / "out"))
    assert code == 0, err
    path = tmp_path / "out" / "crate__panda.h5"
    with h5py.File(path, "r") as f:
        q = f["grasps/qualities"]
        candidates, flex = f["grasps/candidate"][()], q["flex/object_in_gripper"][()]
        assert set(q["label_from"].asstr()[()]) == {"file_label"}
        assert flex.tolist() == [labels[c] for c in candidates] == q["file_label_success"][()].tolist()
    code, _, err = grasp("export", "--db", str(first), "--format", "parquet", "--out", str(tmp_path / "pq"))
    assert code == 0, err
    table = pd.read_parquet(tmp_path / "pq" / "grasps.parquet")
    assert (table["file_label_success"] == table["label"]).all() and set(table["label_from"]) == {"file_label"}
    again = tmp_path / "again.db"  # the export read back losslessly: the labels with it
    code, out, err = grasp("import", str(path), "--db", str(again))
    assert code == 0 and f"the file's labels kept: {held} held" in out, err
    assert _stored(again) == stored


def test_a_file_whose_labels_are_not_0_or_1_is_refused_before_the_database_is_made(db: Path, tmp_path: Path) -> None:
    """Labels are stored since they are kept: one that is no label is refused as calibrate refuses it, before the
    poses are closed and the database opened (it was imported without a word, its labels dropped)."""
    foreign, _ = _labelled(db, tmp_path)
    with h5py.File(foreign, "r+") as f:
        f["grasps/qualities/flex/object_in_gripper"][1] = 2
    code, _, err = grasp("import", str(foreign), "--db", str(tmp_path / "bad.db"))
    one_line_error(code, err, 2, "crate.h5: grasps/qualities/flex/object_in_gripper", "0/1")
    assert not (tmp_path / "bad.db").exists()


def test_an_own_export_written_before_label_from_keeps_no_label_when_re_scored(db: Path, tmp_path: Path) -> None:
    """Our exports before 2026-12-02 wrote no ``label_from``: their ``object_in_gripper`` (a trial's verdict, the
    force-closure flag) was taken, under ``--rescore``, as the labels of the file they came from."""
    path = export(db, "acronym", tmp_path / "ours", "--object", "box") / "box__panda.h5"
    with h5py.File(path, "r+") as f:  # as those files were written
        del f["grasps/qualities/label_from"], f["grasps/qualities/file_label_success"]
        del f["grasps/qualities/file_label_source"]
        assert set(f["grasps/qualities/flex/object_in_gripper"][()].tolist()) == {0, 1}
    code, out, err = grasp("import", str(path), "--rescore", "--db", str(tmp_path / "again.db"))
    assert code == 0 and "re-scored" in out and "labels kept" not in out, out + err
    assert _stored(tmp_path / "again.db") == {}


def test_an_export_of_a_files_labels_re_scored_keeps_them(db: Path, tmp_path: Path) -> None:
    """An export keeps the labels of the file its grasps were imported from in ``file_label_*``; re-scored
    (``--rescore``) it came back without them: its ``label_from`` said it was ours, and nothing else was read."""
    foreign, _ = _labelled(db, tmp_path)
    first = tmp_path / "first.db"
    assert grasp("import", str(foreign), "--db", str(first))[0] == 0
    out_dir = tmp_path / "out"
    code, _, err = grasp("export", "--db", str(first), "--format", "acronym", "--out", str(out_dir), "--label",
                         "force_closure")
    assert code == 0, err
    with h5py.File(out_dir / "crate__panda.h5", "r") as f:
        given = f["grasps/qualities/file_label_success"][()].tolist()
    code, out, err = grasp("import", str(out_dir / "crate__panda.h5"), "--rescore", "--db", str(tmp_path / "re.db"))
    assert code == 0 and "the file's labels kept" in out, out + err
    again = _stored(tmp_path / "re.db")  # re-scored: a grasp's candidate is its row in the export
    assert again and all(s == given[row] and src == "crate.h5 grasps/qualities/flex/object_in_gripper"
                         for row, (s, src) in again.items())


@pytest.mark.parametrize("model", [False, True], ids=["no-model", "shipped-model"])
def test_the_report_compares_p_hold_and_the_score_with_an_imported_files_own_labels(
        db: Path, tmp_path: Path, model: bool, request: pytest.FixtureRequest) -> None:
    """`grasp report` on a database whose only outcomes were an imported file's labels said "no validated grasps"
    (exit 2): the labels the user imported were never compared with p_hold or the score. Now a section names them by
    their source, apart from this project's trials, with the ROC AUCs against them; where a p_hold model applies,
    its reliability table against them too (the diagram's curve, its ECE)."""
    if model:
        request.getfixturevalue("shipped_models")
    foreign, _ = _labelled(db, tmp_path)
    first = tmp_path / "first.db"
    assert grasp("import", str(foreign), "--db", str(first))[0] == 0
    stored = _stored(first)
    held = sum(s for s, _ in stored.values())
    code, out, err = grasp("report", "--db", str(first), "--out", str(tmp_path / "r"))
    assert code == 0, err
    source = "crate.h5 grasps/qualities/flex/object_in_gripper"
    text = (tmp_path / "r" / "report.md").read_text()
    aucs = "ROC AUC of p_hold against them " if model else "dropped; ROC AUC of the analytic score against them "
    for said in (out, text):
        assert f"panda: the imported files' own labels ({source}; the files', not a trial of this project's): " \
               f"{len(stored)} grasps, {held} held, {len(stored) - held} dropped; " in said and aucs in said, said
        ece = f"panda: ECE of p_hold (the imported files' own labels ({source}), {len(stored)} grasps) = "
        assert (ece in said) == model
    assert "trials: " not in text and "No validated grasps: " in text
    # without a model (the Barrett's), no held-out figure to show: it was said to be there
    assert ("No validated grasps: the p_hold model's held-out figures and the imported files' own labels only" in
            text) == model and ("No validated grasps: the imported files' own labels only" in text) != model, text
    assert (tmp_path / "r" / "reliability_panda.png").exists() == model


def test_the_exports_note_on_a_hand_without_p_hold_says_the_files_labels_come_first(db: Path, tmp_path: Path) -> None:
    """The export's note said that a hand without a p_hold model had "its grasps no trial tried labelled by the
    force-closure flag": every grasp of an imported labelled file is labelled by the file's own label."""
    import json

    foreign, _ = _labelled(db, tmp_path)
    first = tmp_path / "first.db"
    assert grasp("import", str(foreign), "--db", str(first))[0] == 0
    for fmt in ("acronym", "parquet"):
        code, out, err = grasp("export", "--db", str(first), "--format", fmt, "--out", str(tmp_path / fmt))
        assert code == 0, err
        notes = json.loads((tmp_path / fmt / f"export-{fmt}.json").read_text())["notes"]
        said = [n for n in notes if "has no calibrated p_hold model" in n]
        assert len(said) == 1 and "its grasps that neither an imported file labels (label_from file_label) nor a " \
            "trial tried are labelled by the force-closure flag" in said[0], notes
        assert said[0] in err + out


def test_a_file_imported_before_its_labels_were_kept_says_so_when_skipped(db: Path, tmp_path: Path) -> None:
    """A database that imported a labelled file before schema v16 holds its grasps, not its labels; importing the file
    again said only "already imported; skipped", the labels nowhere. Now a note says they are missing and how to get
    them (the migrated database's file_labels table is empty: made so here)."""
    foreign, _ = _labelled(db, tmp_path)
    first = tmp_path / "first.db"
    assert grasp("import", str(foreign), "--db", str(first))[0] == 0
    code, out, err = grasp("import", str(foreign), "--db", str(first))
    assert code == 0 and "already imported as crate/panda; skipped" in out and "labels are not in" not in err, err
    with sqlite3.connect(first) as conn:
        n = conn.execute("SELECT COUNT(*) FROM file_labels").fetchone()[0]
        conn.execute("DELETE FROM file_labels")
    conn.close()
    code, out, err = grasp("import", str(foreign), "--db", str(first))
    assert code == 0 and "already imported as crate/panda; skipped" in out, err
    assert n > 0  # the labels of the grasps stored: a pose the re-scoring dropped keeps no label in a new --db either
    assert f"note: {foreign}: the labels of its {n} grasps stored are not in {first} (imported before the database " \
           "kept a file's own labels); import it into a new --db to keep them" in err, err


def test_a_skipped_file_none_of_whose_poses_was_kept_says_nothing_of_its_labels(db: Path, tmp_path: Path) -> None:
    """A labelled file whose every pose the re-scoring dropped (no contact) stores no grasp and so no label: imported
    again into a database of today's schema, it was said to have been "imported before the database kept a file's own
    labels", and a new --db to keep them (which keeps none either)."""
    foreign, _ = _labelled(db, tmp_path)
    with h5py.File(foreign, "r+") as f:
        poses = f["grasps/transforms"][()]
        poses[:, :3, 3] += 5.0  # [m] far from the box: no finger touches it
        f["grasps/transforms"][...] = poses
    first = tmp_path / "first.db"
    code, out, err = grasp("import", str(foreign), "--db", str(first))
    assert code == 0 and "re-scored 0 grasps" in out, out + err
    code, out, err = grasp("import", str(foreign), "--db", str(first))
    assert code == 0 and "already imported as crate/panda; skipped" in out and "labels" not in err, err


def test_report_reads_the_file_labelled_grasps_once(db: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`grasp report` read the grasps an imported file labels four times (the report's p_hold section and its
    lines, each through both `calibration` and `labelled`): now once, its figures the same."""
    from planner.db.store import Database

    foreign, _ = _labelled(db, tmp_path)
    first = tmp_path / "first.db"
    assert grasp("import", str(foreign), "--db", str(first))[0] == 0
    reads = []
    validated = Database.validated

    def counted(self: Database, **kwargs: bool) -> list:
        reads.append(kwargs.get("file_labels", False))
        return validated(self, **kwargs)

    monkeypatch.setattr(Database, "validated", counted)
    code, out, err = grasp("report", "--db", str(first), "--out", str(tmp_path / "r"))
    assert code == 0, err
    assert reads.count(True) == 1, reads
    assert "panda: the imported files' own labels (crate.h5 grasps/qualities/flex/object_in_gripper; " in out, out


def test_a_file_named_as_one_the_shipped_model_was_fitted_on_is_not_said_in_sample(db: Path, tmp_path: Path,
                                                                                  shipped_models: None) -> None:
    """The shipped model names the dev set's tuning files and records their bytes' sha256: a file made here under one
    of those names was told "fitted on this file's labels" (matched by name), its labels never seen by the fit."""
    from planner.calibration.model import default_model

    model = default_model("panda")
    assert model is not None and len(model.labels) == len(model.label_hashes) == 46
    foreign, _ = foreign_file(db, tmp_path, "box", model.labels[0].removesuffix(".h5"))  # that name, made here
    with h5py.File(foreign, "r+") as f:
        key = "grasps/qualities/flex/object_in_gripper"
        f[key][...] = np.arange(len(f[key])) % 2
    mine = tmp_path / "mine.db"
    code, out, err = grasp("import", str(foreign), "--db", str(mine))
    assert code == 0 and "the file's labels kept" in out and "in-sample" not in err, err
    code, out, err = grasp("report", "--db", str(mine), "--out", str(tmp_path / "r"))
    assert code == 0 and "the imported files' own labels" in out and "in-sample" not in out, out


def test_in_sample_is_told_by_the_label_files_bytes_not_their_names(db: Path, tmp_path: Path,
                                                                    shipped_models: None) -> None:
    """A model fitted on robot/mug/outcomes.h5 told an import of robot/cup/outcomes.h5 "fitted on this file's labels"
    (matched by name), and a renamed copy of a fitted file was not told: a model that records its files' sha256 is
    matched by content; one that records none keeps the name."""
    from dataclasses import replace

    from planner.calibration.labels import file_digest
    from planner.calibration.model import default_model
    from planner.db.store import open_for_writing

    fitted, _ = _labelled(db, tmp_path)  # foreign/grasps/crate.h5
    other = tmp_path / "cup" / "foreign" / "grasps" / "crate.h5"
    shutil.copytree(tmp_path / "foreign", other.parents[1])
    with h5py.File(other, "r+") as f:  # the same name, other labels: other bytes
        f["grasps/qualities/flex/object_in_gripper"][0] ^= 1
    renamed = fitted.with_name("renamed.h5")
    shutil.copy(fitted, renamed)
    shipped = default_model("panda")
    assert shipped is not None
    by_bytes = replace(shipped, labels=("crate.h5",), label_hashes=(file_digest(fitted),))
    by_name = replace(shipped, labels=("crate.h5",), label_hashes=())

    def said(model: object, path: Path, name: str) -> tuple[bool, bool, bool]:
        """Whether import, report and best say the imported file's labels are in-sample."""
        out_db = tmp_path / f"{name}.db"
        with open_for_writing(out_db) as base:
            base.write_model(model, "test", base.rule())  # type: ignore[arg-type]
        code, _, err = grasp("import", str(path), "--db", str(out_db))
        assert code == 0, err
        code, out, rep = grasp("report", "--db", str(out_db), "--out", str(tmp_path / f"{name}_r"))
        assert code == 0, rep
        with sqlite3.connect(out_db) as conn:
            (obj,), = conn.execute("SELECT DISTINCT object FROM grasps")
        code, best, best_err = grasp("best", obj, "--hand", "panda", "--db", str(out_db), "--top", "2")
        assert code == 0, best_err
        notes = [line for line in best_err.splitlines() if "in-sample" in line]
        assert notes in ([], ["note: in-sample: 2 of these grasps carry the labels of a file the panda's p_hold model "
                              "was fitted on (the file they were imported from): their p_hold against those labels is "
                              "no check of it"]), best_err
        return "fitted on this file's labels" in err, "in-sample: the p_hold model was fitted on" in out, bool(notes)

    assert said(by_bytes, fitted, "fitted") == (True, True, True)
    assert said(by_bytes, other, "other") == (False, False, False)
    assert said(by_bytes, renamed, "renamed") == (True, True, True)
    assert said(by_name, other, "named") == (True, True, True)  # no hashes: the name rule, as before


def test_best_json_says_which_grasps_are_in_sample(db: Path, tmp_path: Path, shipped_models: None) -> None:
    """`best` printed an in-sample note where its grasps carry the labels of a file p_hold was fitted on; `--json`,
    what a script reads, had no such field."""
    import json
    from dataclasses import replace

    from planner.calibration.labels import file_digest
    from planner.calibration.model import default_model
    from planner.db.store import open_for_writing

    fitted, _ = _labelled(db, tmp_path)
    shipped = default_model("panda")
    assert shipped is not None
    for name, hashes in (("fitted", (file_digest(fitted),)), ("other", ("0" * 64,))):
        out_db = tmp_path / f"{name}.db"
        with open_for_writing(out_db) as base:
            base.write_model(replace(shipped, labels=("crate.h5",), label_hashes=hashes), "test", base.rule())
        code, _, err = grasp("import", str(fitted), "--db", str(out_db))
        assert code == 0, err
        code, out, err = grasp("best", "crate", "--hand", "panda", "--db", str(out_db), "--top", "2", "--json")
        assert code == 0, err
        assert [g["in_sample"] for g in json.loads(out)] == [name == "fitted"] * 2, out
        code, out, err = grasp("best", "crate", "--hand", "panda", "--db", str(out_db), "--on-table", "--no-plan",
                               "--stable-poses", "1")
        assert code == 0, err
        assert ("note: in-sample: " in err) == (name == "fitted"), err  # as plain `best` says it
