"""``grasp calibrate`` end to end on labelled files the test makes, the shipped model, and p_hold in best/exports."""

from __future__ import annotations

import json
import re
import shutil
import sqlite3
from pathlib import Path

import h5py
import numpy as np
import pytest
from helpers import FAST, grasp, one_line_error

from planner.calibration.model import default_model
from planner.db.ranking import rule_measures
from planner.db.store import open_db

LABEL = "grasps/qualities/flex/object_in_gripper"


def labelled_files(validated_db: Path, tmp_path: Path) -> list[Path]:
    """The box and the sphere exported in ACRONYM layout, labelled 1 where epsilon is above its file's median."""
    out = tmp_path / "labels"
    code, _, err = grasp("export", "--db", str(validated_db), "--format", "acronym", "--out", str(out), "--quiet")
    assert code == 0, err
    files = sorted(out.rglob("*.h5"))
    for path in files:
        with h5py.File(path, "r+") as f:
            eps = f["grasps/qualities/epsilon"][:]
            f[LABEL][...] = (eps > np.median(eps)).astype(np.int64)
    return files


def test_calibrate_fits_reports_and_stores_a_model_that_best_and_exports_use(validated_db: Path,
                                                                             tmp_path: Path) -> None:
    files = labelled_files(validated_db, tmp_path)
    assert len(files) == 2
    db = tmp_path / "g.db"
    shutil.copy(validated_db, db)
    png = tmp_path / "plots" / "rel.png"  # a folder made by the write, and said
    code, out, err = grasp("calibrate", *map(str, files), "--db", str(db), "--poses", "12", "--folds", "2",
                           "--plot", str(png), "--model-out", str(tmp_path / "m.toml"))
    assert code == 0, err
    assert f"{png}: its reliability diagram (made the folder {png.parent})" in out.splitlines(), out
    assert f"{tmp_path / 'm.toml'}: the fitted model" in out.splitlines(), out  # its folder was there
    assert "held out (2 folds grouped by object)" in out and "ECE" in out and "stored in" in out
    assert "95% intervals over objects" in out and "from so few objects they understate the spread" in out
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and (tmp_path / "m.toml").read_text().startswith("# p_hold")
    with open_db(db, create=False, readonly=True) as d:
        assert d.model("panda") is not None and "labels" in d.model_source("panda")
        grasps = d.best("box", "panda", 1000)
        rule = d.rule()
        rows = {name: d.object_row(name) for name in ("box", "sphere")}
        domain = d.model("panda").domain  # type: ignore[union-attr]
        assert d.model_domain("panda") == domain  # the stored model's, without building it
    props = [r.properties() for r in rows.values() if r is not None]  # the labelled files' objects, as exported
    assert len(props) == 2 and set(domain) == {"density", "friction", "mass"}
    for k, (low, high) in domain.items():
        assert low == pytest.approx(min(p[k] for p in props), rel=1e-3)
        assert high == pytest.approx(max(p[k] for p in props), rel=1e-3)
    assert all(0.0 <= g.p_hold <= 1.0 for g in grasps)  # type: ignore[operator]
    assert np.allclose([g.score for g in grasps], rule.scores(rule_measures(grasps)))  # scored by p_hold
    code, out, err = grasp("best", "box", "--hand", "panda", "--db", str(db))
    assert code == 0, err
    assert "p_hold n/a" not in out and f"p_hold {grasps[0].p_hold:.3f} (calibrated" in out
    code, out, err = grasp("best", "box", "--hand", "panda", "--db", str(db), "--explain")
    assert code == 0, err  # the analytic score is p_hold: its log-odds feature by feature (a line or a spline)
    assert "analytic = p_hold = 1 / (1 + exp(-logit))" in out
    assert re.search(r"^      epsilon~?: x [-0-9.e]+ -> [-+][0-9.]+$", out, re.M), out
    assert f"-> p_hold {grasps[0].p_hold:.4f} (stored {grasps[0].p_hold:.4f})" in out
    assert "interactions (the model's trees over these inputs together): " in out  # the trees' part, one line
    assert "[trees]" in (tmp_path / "m.toml").read_text()
    code, _, err = grasp("calibrate", *map(str, files), "--db", str(db), "--poses", "12", "--folds", "2", "--no-store",
                         "--no-trees", "--model-out", str(tmp_path / "additive.toml"))
    assert code == 0, err
    assert "[trees]" not in (tmp_path / "additive.toml").read_text()
    code, _, err = grasp("export", "--db", str(db), "--format", "csv", "--out", str(tmp_path / "csv"), "--quiet")
    assert code == 0, err
    header = next((tmp_path / "csv").rglob("*.csv")).read_text().splitlines()[0].split(",")
    assert "p_hold" in header
    code, out, err = grasp("report", "--db", str(db), "--out", str(tmp_path / "rep"))
    assert code == 0, err
    assert "panda: ECE of p_hold (held out on its labels: the model's source" in out
    assert (tmp_path / "rep" / "reliability_panda.png").exists()
    assert re.search(r"held out on its labels: the model's source, \d+ grasps\) = [0-9.]+ \[[0-9.]+, [0-9.]+\] "
                     r"\(95% over objects", out), out


@pytest.mark.parametrize("args, message", [
    (["calibrate", "nowhere.h5"], "file not found"),
    (["calibrate", "{file}", "--folds", "1"], "--folds must be at least 2"),
    (["calibrate", "{file}", "--plot", "x.jpg"], "as PNG"),
])
def test_bad_calibrate_input_is_one_line_and_exit_2(args: list[str], message: str, validated_db: Path,
                                                   tmp_path: Path) -> None:
    file = labelled_files(validated_db, tmp_path)[0]
    code, _, err = grasp(*[a.replace("{file}", str(file)) for a in args], "--db", str(tmp_path / "g.db"))
    assert code == 2 and message in err and "Traceback" not in err


def test_one_object_cannot_be_cross_validated_by_object(validated_db: Path, tmp_path: Path) -> None:
    file = labelled_files(validated_db, tmp_path)[0]
    code, _, err = grasp("calibrate", str(file), "--poses", "5", "--no-store")
    assert code == 2 and "at least 2 objects" in err


def test_the_shipped_panda_model_loads_and_rescores_a_database(box_db: Path, tmp_path: Path,
                                                              shipped_models: None) -> None:
    model = default_model("panda")
    assert model is not None and model.hand == "panda" and "tuning" in model.source
    assert model.held_out is not None and abs(model.held_out.ece - model.figures["ece"]) < 1e-12
    db = tmp_path / "g.db"
    shutil.copy(box_db, db)
    with open_db(db) as d:
        assert d.apply_rule(d.rule())  # scored without the model: re-scored with it
        assert not d.apply_rule(d.rule())
        grasps = d.best("box", "panda", 1000)
    assert all(g.p_hold is not None for g in grasps)
    with sqlite3.connect(db) as conn:  # a stored column, written with the scores
        assert conn.execute("SELECT COUNT(*) FROM grasps WHERE p_hold IS NULL").fetchone()[0] == 0
    fc = [g.force_closure for g in grasps]
    assert fc == sorted(fc, reverse=True)  # force closure first


def test_best_and_report_say_where_the_shipped_p_hold_is_extrapolated(box_db: Path, tmp_path: Path,
                                                                     shipped_models: None) -> None:
    from planner.calibration.logistic import default_domain

    model = default_model("panda")
    assert model is not None and model.domain["friction"] == (1.0, 1.0)  # ACRONYM's labels: friction 1
    assert default_domain("panda") == model.domain  # read from its [domain] table alone, as `grasp best` does
    assert model.domain["density"][0] == pytest.approx(150.0, rel=1e-3)  # ... and 150 kg/m^3
    db = tmp_path / "g.db"
    shutil.copy(box_db, db)  # the box: 0.2 kg, friction 0.5
    code, out, err = grasp("best", "box", "--hand", "panda", "--db", str(db))
    assert code == 0, err
    note = [line for line in out.splitlines() if line.startswith("note: p_hold is extrapolated for box")]
    assert len(note) == 1 and "friction 0.5 (labels: 1)" in note[0] and "density" in note[0], out
    code, out, err = grasp("best", "box", "--hand", "panda", "--db", str(db), "--json")
    assert code == 0, err
    assert any(w.startswith("friction 0.5") for w in json.loads(out)[0]["p_hold_outside"])
    code, out, err = grasp("report", "--db", str(db), "--out", str(tmp_path / "rep"))
    assert code == 0, err
    assert "panda: p_hold of box is extrapolated" in out
    inside = tmp_path / "inside.db"  # the same box at the labels' density and friction: nothing to say
    code, _, err = grasp("generate", "box", "--hand", "panda", "--db", str(inside), "--density", "150",
                         "--friction", "1", "--quiet", *FAST)
    assert code == 0, err
    code, out, err = grasp("best", "box", "--hand", "panda", "--db", str(inside))
    assert code == 0, err
    assert "p_hold" in out and "extrapolated" not in out
    code, out, err = grasp("best", "box", "--hand", "panda", "--db", str(inside), "--json")
    assert code == 0 and json.loads(out)[0]["p_hold_outside"] == []


def test_best_at_a_pose_or_on_the_table_says_where_p_hold_is_extrapolated(box_db: Path, tmp_path: Path,
                                                                          shipped_models: None) -> None:
    """`best --object-pose` and `--on-table` print the same grasps with arm joints: their p_hold is as
    extrapolated as plain `best`'s, which said so while they (and `--object-pose --json`'s `p_hold_outside`, which
    the README lists for every `best --json`) said nothing."""
    db = tmp_path / "g.db"
    shutil.copy(box_db, db)  # the box: 0.2 kg, friction 0.5
    at = ["--object-pose", "0.5,0,0.05,0,0,0,1", "--max-candidates", "20"]
    for how in (at, ["--on-table", "--stable-poses", "1", "--max-candidates", "20"]):
        code, out, err = grasp("best", "box", "--hand", "panda", "--db", str(db), *how)
        assert code == 0, err
        note = [line for line in out.splitlines() if line.startswith("note: p_hold is extrapolated for box")]
        assert len(note) == 1 and "friction 0.5 (labels: 1)" in note[0], out
    code, out, err = grasp("best", "box", "--hand", "panda", "--db", str(db), *at, "--json")
    assert code == 0, err
    assert any(w.startswith("friction 0.5") for w in json.loads(out)[0]["p_hold_outside"])


def test_calibrate_with_trials_fits_the_update_that_labels_and_ranks_validated_grasps(validated_db: Path,
                                                                                      tmp_path: Path) -> None:
    files = labelled_files(validated_db, tmp_path)
    db = tmp_path / "g.db"
    shutil.copy(validated_db, db)
    code, out, err = grasp("calibrate", *map(str, files), "--db", str(db), "--poses", "12", "--folds", "2",
                           "--no-trees", "--trial", "4", "--engine", "mujoco", "--model-out", str(tmp_path / "m.toml"))
    assert code == 0, err
    assert re.search(r"^\d+ grasps tried in mujoco: agreement with the labels: the verdict 0\.\d{3}", out, re.M), out
    interval = r"\[[01]\.\d{3}, [01]\.\d{3}\]"  # its 95% interval over objects
    assert re.search(r"p_hold given the verdict >= 0\.5 [01]\.\d{3} " + interval + r" \(held out\)", out), out
    assert "[updates.mujoco]" in (tmp_path / "m.toml").read_text()
    with open_db(db, create=False, readonly=True) as d:
        model = d.model("panda")
    assert model is not None and set(model.updates) == {"mujoco"} and model.updates["mujoco"].grasps > 0
    code, _, err = grasp("validate", "--db", str(db), "--object", "box", "--hand", "panda", "--top", "2", "--robust",
                         "0", "--engine", "mujoco", "--workers", "1")
    assert code == 0, err
    with open_db(db, create=False, readonly=True) as d:
        grasps = d.best("box", "panda", 1000)
        rule = d.rule()
    tried = [g for g in grasps if g.mujoco is not None]
    assert len(tried) == 2
    for g in grasps:  # p_hold updated by the MuJoCo verdict where it tried the grasp, and only there
        if g.mujoco is None:
            assert g.p_hold_trial is None
        else:
            expected = model.updates["mujoco"].apply(np.array([g.p_hold]), np.array([float(g.mujoco.success)]))[0]
            assert g.p_hold_trial == pytest.approx(expected, rel=1e-9)
    assert np.allclose([g.score for g in grasps], rule.scores(rule_measures(grasps)))
    terms = rule.terms(rule_measures(tried))  # the verdict is in p_hold_trial: it does not multiply again
    assert np.allclose(terms["analytic"], [g.p_hold_trial for g in tried]) and np.all(terms["success_factor"] == 1)
    from planner.present.describe import describe, explain, probability
    from planner.specs.hands import hand_frame

    head = describe(tried[0], hand_frame("panda"))[0]
    verdict = "held" if tried[0].mujoco.success else "dropped"  # type: ignore[union-attr]
    assert f", {probability(tried[0].p_hold_trial)} given its trial's verdict ({verdict})" in head  # type: ignore[arg-type]
    lines = "\n".join(explain(tried[0], rule, model))
    assert f"(1 / (1 + exp(-({model.updates['mujoco'].slope:.4f} x logit" in lines
    assert f"analytic = p_hold_trial = {tried[0].p_hold_trial:.4f}: p_hold updated by the trial's verdict" in lines
    assert "counted in p_hold_trial: 1" in lines
    out_dir = tmp_path / "csv"
    code, _, err = grasp("export", "--db", str(db), "--format", "csv", "--out", str(out_dir), "--quiet",
                         "--object", "box", "--label", "p_hold_trial")
    assert code == 0, err
    import csv

    rows = list(csv.DictReader(next(out_dir.rglob("*.csv")).open()))
    assert len(rows) == 2 and {r["label_from"] for r in rows} == {"p_hold_trial"}
    assert sorted(int(r["label"]) for r in rows) == sorted(int(g.p_hold_trial >= 0.5) for g in tried)  # type: ignore[operator]


def test_a_database_that_cannot_take_the_model_is_refused_before_the_fit(validated_db: Path, tmp_path: Path) -> None:
    """A --db that is a folder (or locked by a writer, or of a newer schema) failed only after the whole fit
    (23 s on a helper's run), the model thrown away; now before any pose is re-scored."""
    files = labelled_files(validated_db, tmp_path)  # two objects: one alone is refused before the database is
    folder = tmp_path / "folder.db"
    folder.mkdir()
    code, _, err = grasp("calibrate", *map(str, files), "--db", str(folder), "--poses", "12", "--folds", "2")
    assert code == 3 and "poses closed on the object" not in err and len(err.strip().splitlines()) == 1, err
    code, _, err = grasp("calibrate", str(files[0]), "--db", str(tmp_path / "g.db"), "--workers", "0")
    assert code == 2 and "--workers must be at least 1" in err, err


@pytest.mark.parametrize("args, message", [
    (["{missing}"], "file not found"),
    (["{folder}"], "is a folder; give its .h5 files"),
    (["{file}", "--trial", "-1"], "--trial must be >= 0"),
    (["{file}", "--poses", "-1"], "--poses must be 0 (every pose) or a count of at least 1, got -1"),
])
def test_a_refused_calibrate_leaves_no_database_behind(args: list[str], message: str, validated_db: Path,
                                                       tmp_path: Path) -> None:
    """A missing label file, a folder, a bad --trial or --poses were refused only once the database had been
    created (an empty grasp database and its lock file left at --db); a folder was said to be 'not found'."""
    file = labelled_files(validated_db, tmp_path)[0]
    (tmp_path / "labels_folder").mkdir()
    named = {"{missing}": str(tmp_path / "nowhere.h5"), "{folder}": str(tmp_path / "labels_folder"),
             "{file}": str(file)}
    db = tmp_path / "new.db"
    code, _, err = grasp("calibrate", *[named.get(a, a) for a in args], "--db", str(db))
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1, err
    assert not db.exists() and not Path(f"{db}.lock").exists()


@pytest.mark.parametrize("option", ["--plot", "--model-out"])
def test_an_output_that_cannot_be_written_is_refused_before_the_fit(option: str, validated_db: Path,
                                                                    tmp_path: Path) -> None:
    """--plot or --model-out under a file (or naming a folder) failed after the whole fit, as an internal error
    (exit 1), the model already stored; now one line, exit 2, before any pose is re-scored or the db opened."""
    file = labelled_files(validated_db, tmp_path)[0]
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    folder = tmp_path / "a_folder.png"
    folder.mkdir()
    db = tmp_path / "new.db"
    for out in (blocker / "out.png", folder):
        code, _, err = grasp("calibrate", str(file), "--db", str(db), "--poses", "12", "--folds", "2", option,
                             str(out))
        assert code == 2 and option in err and "poses closed" not in err, err
        assert len(err.strip().splitlines()) == 1 and not db.exists(), err


def test_a_hand_without_a_width_prints_its_width_baseline_as_n_a(monkeypatch: pytest.MonkeyPatch) -> None:
    """A Barrett's or Allegro's files have no closed width: the summary printed 'width baseline nan' (the
    per-object lines already said n/a)."""
    from types import SimpleNamespace

    from planner import api

    figures = {"grasps": 80, "objects": 2, "success_rate": 0.26, "folds": 2, "auc_mean": 0.52,
               "auc_width": float("nan"), "auc_pooled": 0.5, "top10": 0.2, "ece": 0.05, "agreement": 0.74,
               "log_loss": 0.59}
    result = SimpleNamespace(figures=figures, model=SimpleNamespace(hand="barrett"),
                             per_object=[{"object": "box.h5", "grasps": 40, "success_rate": 0.23,
                                          "auc_p_hold": 0.52, "auc_width": float("nan")}])
    monkeypatch.setattr(api, "calibrate", lambda *a, **kw: result)
    code, out, err = grasp("calibrate", "x.h5", "--no-store")
    assert code == 0, err
    assert "(width baseline n/a)" in out and "nan" not in out, out


def test_outputs_in_folders_not_made_yet_are_written(validated_db: Path, tmp_path: Path) -> None:
    """--plot "new dir/p.png" passed the check before the fit (its folder may be made, as `grasp show` makes
    one), then failed after the whole fit: "No such file or directory", exit 2."""
    files = labelled_files(validated_db, tmp_path)
    png, model = tmp_path / "new dir" / "p.png", tmp_path / "other" / "m.toml"
    code, _, err = grasp("calibrate", *map(str, files), "--no-store", "--poses", "12", "--folds", "2",
                         "--plot", str(png), "--model-out", str(model))
    assert code == 0, err
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and model.read_text().startswith("# p_hold")


def test_a_users_own_labels_without_gripper_type_calibrate_with_hand(validated_db: Path, tmp_path: Path) -> None:
    """Real-robot outcomes written as the README says (transforms, labels, the object's file and scale) were
    refused even with --hand: "no 'gripper/type' dataset; not an ACRONYM grasp file"."""
    files = labelled_files(validated_db, tmp_path)
    for path in files:
        with h5py.File(path, "r+") as f:
            del f["gripper/type"]
    code, _, err = grasp("calibrate", *map(str, files), "--no-store", "--poses", "12", "--folds", "2")
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "no 'gripper/type' dataset says which hand made its grasps; pass --hand" in err, err
    code, out, err = grasp("calibrate", *map(str, files), "--no-store", "--poses", "12", "--folds", "2",
                           "--hand", "panda")
    assert code == 0 and "p_hold for panda" in out, err


def test_files_of_one_object_are_refused_before_any_pose_is_closed(validated_db: Path, tmp_path: Path,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """Two label files of one object: every sampled pose of both was closed again (minutes on real files), then
    refused for having one object. Refused first, in one line, nothing closed and no database made."""
    from planner.datasets import importer

    first = labelled_files(validated_db, tmp_path)[0]
    second = tmp_path / "again.h5"
    shutil.copy(first, second)
    with h5py.File(second, "r+") as f:  # other labels, the same object: not a copy
        f[LABEL][...] = 1 - f[LABEL][...]
    closed: list[object] = []
    monkeypatch.setattr(importer, "rescore_poses", lambda *a, **k: closed.append(a))
    code, _, err = grasp("calibrate", str(first), str(second), "--poses", "5", "--db", str(tmp_path / "g.db"))
    one_line_error(code, err, 2, "at least 2 objects", "the 2 file(s) given are all of")
    assert closed == [] and not (tmp_path / "g.db").exists()


def test_calibrate_says_which_shipped_model_its_stored_one_replaces(validated_db: Path, tmp_path: Path,
                                                                   shipped_models: None) -> None:
    """A model fitted on a few labelled files replaces the shipped one for the database's grasps: the user is told
    what it replaces and how that one scored held out (a new user stored a model of ECE 0.138 over 0.016 unwarned)."""
    from planner import api

    files = labelled_files(validated_db, tmp_path)
    db = tmp_path / "g.db"
    shutil.copy(validated_db, db)
    code, _, err = grasp("calibrate", *map(str, files), "--db", str(db), "--poses", "12", "--folds", "2")
    assert code == 0, err
    shipped = api.shipped_figures("panda")
    assert shipped, "the project ships a Panda model"
    assert (f"replaces, for this database's panda grasps, the shipped model (calibration/panda.toml, ACRONYM's dev "
            f"set: {int(shipped['objects'])} objects, held-out AUC {shipped['auc_mean']:.3f}") in err, err
    code, _, err = grasp("calibrate", *map(str, files), "--db", str(db), "--poses", "12", "--folds", "2",
                         "--no-store")
    assert code == 0 and "replaces" not in err, err
