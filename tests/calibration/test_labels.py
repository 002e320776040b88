"""The labelled files ``grasp calibrate`` reads (planner/calibration/labels.py): paths, objects, hands, labels."""

from __future__ import annotations

import hashlib
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
from helpers import grasp, one_line_error

from tests.calibration.test_calibrate_cli import LABEL, labelled_files

FAST_FIT = ("--poses", "6", "--folds", "2", "--no-trees", "--no-store")


def acronym_layout(files: list[Path], root: Path) -> list[Path]:
    """Each labelled file as ACRONYM keeps it: ``root/grasps/<stem>.h5`` naming ``meshes/<object>.obj`` (one folder
    up) as its object/file, without this project's object/name and mesh hash."""
    (root / "grasps").mkdir(parents=True)
    out = []
    for path in files:
        target = root / "grasps" / path.name
        shutil.copy(path, target)
        with h5py.File(target, "r+") as f:
            del f["object/name"], f["object/mesh_sha256"]
            mesh = f["object/file"][()].decode()
        (root / "meshes").mkdir(exist_ok=True)
        shutil.copy(path.parent / mesh, root / mesh)
        out.append(target)
    return out


def tiny_file(path: Path, **datasets: object) -> Path:
    """A labelled Panda file of three identity poses; ``datasets`` (key with '__' for '/') added or replaced."""
    with h5py.File(path, "w") as f:
        f["gripper/type"], f["grasps/transforms"] = "franka_panda", np.tile(np.eye(4), (3, 1, 1))
        f["object/file"], f["object/scale"], f[LABEL] = "meshes/nowhere.obj", 1.0, np.array([1, 0, 1])
        for key, value in datasets.items():
            name = key.replace("__", "/")
            if name in f:
                del f[name]
            f[name] = value
    return path


def test_relative_paths_find_acronyms_meshes_folder(validated_db: Path, tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """`cd acr/grasps && grasp calibrate r3.h5 ...` looked for meshes/ at '.' twice (Path('r3.h5').parent.parent)."""
    files = acronym_layout(labelled_files(validated_db, tmp_path), tmp_path / "acr")
    monkeypatch.chdir(tmp_path / "acr" / "grasps")
    code, out, err = grasp("calibrate", *(f.name for f in files), *FAST_FIT)
    assert code == 0 and "held out (2 folds grouped by object)" in out, err


def test_a_missing_mesh_is_named_with_calibrates_own_hint(tmp_path: Path) -> None:
    """The hint said `pass --object`, an option of `grasp import` that `grasp calibrate` does not have."""
    code, _, err = grasp("calibrate", str(tiny_file(tmp_path / "r1.h5")), "--no-store")
    one_line_error(code, err, 2, "r1.h5: object/file 'meshes/nowhere.obj' not found", "put the mesh there")
    assert "--object" not in err


def test_a_built_in_name_without_a_hash_is_the_files_own_mesh_where_that_differs(tmp_path: Path) -> None:
    """A user's file naming its own mesh 'box' (no object/mesh_sha256) was fitted on the built-in box."""
    import trimesh

    from planner.datasets import importer
    from planner.datasets.acronym import read_header
    from planner.datasets.file_objects import object_spec
    from planner.geometry.solid import load_object

    mesh = tmp_path / "meshes" / "box.obj"
    mesh.parent.mkdir()
    trimesh.creation.box((0.05, 0.06, 0.07)).export(mesh)
    path = tiny_file(tmp_path / "mine.h5", object__name="box", object__file="meshes/box.obj")
    for spec in (importer.read_for_rescoring(path)[1], object_spec(read_header(path), None, "import")):
        assert spec.kind == "mesh" and spec.source == str(mesh.resolve()) and spec.name == "box"
    load_object("box").mesh.export(mesh)  # the built-in's own mesh: the built-in
    assert importer.read_for_rescoring(path)[1].kind == "box"


def boxes(folder: Path, *grippers: str) -> list[Path]:
    """Tiny labelled files of a box mesh (``folder/meshes/box.obj``), one per gripper type."""
    import trimesh

    (folder / "meshes").mkdir(parents=True, exist_ok=True)
    trimesh.creation.box((0.05, 0.06, 0.07)).export(folder / "meshes" / "box.obj")
    return [tiny_file(folder / f"{i}_{g}.h5", gripper__type=g, object__file="meshes/box.obj")
            for i, g in enumerate(grippers)]


def test_a_file_of_another_hand_is_named_before_any_pose_is_rescored(tmp_path: Path) -> None:
    """--hand panda silently re-scored a barrett-typed file with the Panda; a barrett file among Panda files was
    refused only after every file was re-scored, without naming it."""
    files = boxes(tmp_path, "franka_panda", "barrett", "panda")
    code, _, err = grasp("calibrate", *map(str, files), "--no-store")  # one line: no file re-scored first
    one_line_error(code, err, 2, "1_barrett.h5: gripper/type 'barrett'", "the other files' hand is panda",
                   "one hand at a time")
    code, _, err = grasp("calibrate", str(files[1]), "--hand", "panda", "--no-store")
    one_line_error(code, err, 2, "1_barrett.h5: gripper/type 'barrett' is not --hand panda")


def test_files_of_one_name_in_two_folders_are_two_files_and_a_file_given_twice_is_refused(
        validated_db: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """day1/grasps.h5 and day2/grasps.h5 were one stem 'grasps': the domain kept one object's properties, the
    top-10 merged the files, the source listed ["grasps.h5", "grasps.h5"]; a file given twice counted twice."""
    import json

    from planner.db.store import open_db

    box, sphere = labelled_files(validated_db, tmp_path)
    days = []
    for day, src in (("day1", box), ("day2", sphere)):
        shutil.copytree(src.parent / "meshes", tmp_path / day / "meshes")
        days.append(Path(shutil.copy(src, tmp_path / day / "grasps.h5")))
    db = tmp_path / "g.db"
    shutil.copy(validated_db, db)
    code, out, err = grasp("calibrate", *map(str, days), *FAST_FIT[:-1], "--db", str(db))
    assert code == 0, err
    with open_db(db, create=False, readonly=True) as d:
        domain = d.model_domain("panda")
        source = json.loads(d.model_source("panda"))
        masses = [d.object_row(name).properties()["mass"] for name in ("box", "sphere")]  # type: ignore[union-attr]
        model = d.model("panda")
    assert source["labels"] == ["day1/grasps.h5", "day2/grasps.h5"]
    assert model is not None and model.labels == ("day1/grasps.h5", "day2/grasps.h5")  # and each file's bytes' hash:
    assert model.label_hashes == tuple(hashlib.sha256(p.read_bytes()).hexdigest() for p in days)  # in-sample by them
    assert domain["mass"] == pytest.approx((min(masses), max(masses)), rel=1e-3) and masses[0] != masses[1]
    monkeypatch.chdir(box.parent)  # overlapping globs give one file twice, spelt alike or not
    code, _, err = grasp("calibrate", str(box), box.name, str(sphere), *FAST_FIT)
    one_line_error(code, err, 2, f"{box.name}: given twice (as {box} and {box.name})", "give each file once")
    code, _, err = grasp("calibrate", box.name, box.name, str(sphere), *FAST_FIT)
    one_line_error(code, err, 2, f"{box.name}: given twice: its labels would count twice")


def test_a_copy_of_a_label_file_under_another_name_is_refused(validated_db: Path, tmp_path: Path) -> None:
    """A byte-identical copy (a dataset folder holding one file twice) was two files: its labels counted twice."""
    box, sphere = labelled_files(validated_db, tmp_path)
    (tmp_path / "again").mkdir()
    shutil.copytree(box.parent / "meshes", tmp_path / "again" / "meshes")
    copy = Path(shutil.copy(box, tmp_path / "again" / "copy.h5"))
    code, _, err = grasp("calibrate", str(box), str(sphere), str(copy), *FAST_FIT)
    one_line_error(code, err, 2, f"{copy}: the same bytes as {box} (a copy): its labels would count twice",
                   "give each file once")


@pytest.mark.parametrize("labels, message", [
    (np.array([b"yes", b"no", b"yes"]), "holds text values (b'yes', b'no', ...)"),
    (np.array([[1, 0], [0, 1], [1, 1]]), "has shape (3, 2)"),
])
def test_labels_calibrate_cannot_read_are_one_line_errors(tmp_path: Path, labels: np.ndarray, message: str) -> None:
    """Text labels and an (N, 2) array were `internal error: ValueError` (exit 1)."""
    path = boxes(tmp_path, "panda")[0]
    with h5py.File(path, "r+") as f:
        del f[LABEL]
        f[LABEL] = labels
    code, _, err = grasp("calibrate", str(path), "--no-store")
    one_line_error(code, err, 2, f"0_panda.h5: {LABEL} {message}")


def test_copies_are_told_apart_without_pythons_3_11_file_digest(tmp_path: Path,
                                                                monkeypatch: pytest.MonkeyPatch) -> None:
    """The project runs on Python 3.10 (pyproject's requires-python), which has no hashlib.file_digest: the
    copy check gave 'internal error: AttributeError' for any two label files there."""
    import hashlib

    from planner.calibration.labels import label_names
    from planner.errors import InputError

    monkeypatch.delattr(hashlib, "file_digest", raising=False)  # as on Python 3.10
    (tmp_path / "a").mkdir()
    one, other, copy = tmp_path / "one.h5", tmp_path / "other.h5", tmp_path / "a" / "copy.h5"
    one.write_bytes(b"\x89HDF" + bytes(3 << 20))  # over one block read
    other.write_bytes(b"\x89HDF" + bytes(3 << 20) + b"\x01")
    shutil.copy(one, copy)
    assert label_names([one, other]) == ["one.h5", "other.h5"]
    with pytest.raises(InputError, match=r"copy.h5: the same bytes as .*one.h5 \(a copy\)"):
        label_names([one, other, copy])


def test_the_api_takes_poses_0_as_every_pose_as_the_command_line_does(tmp_path: Path) -> None:
    """``api.calibrate(..., poses=0)`` was refused with "--poses must be 0 (every pose) or a count of at least
    1, got 0": the CLI turns 0 into None (every pose), the API did not."""
    from planner import api
    from planner.errors import InputError

    with pytest.raises(InputError) as refused:
        api.calibrate([tmp_path / "none.h5"], db_path=None, poses=0)
    assert "--poses" not in str(refused.value) and "none.h5" in str(refused.value), refused.value
    with pytest.raises(InputError, match="--poses must be 0 .every pose. or a count of at least 1, got -1"):
        api.calibrate([tmp_path / "none.h5"], db_path=None, poses=-1)


def test_an_own_files_poses_close_from_its_openings_as_import_rescore_closes_them(tmp_path: Path) -> None:
    """Issue 26: ``import --rescore`` closes an own export's pose from the opening the file planned it with; calibrate
    closed it from the widest preshape still (a Barrett pinch as a spread-0 wrap), so a p_hold fitted on an own
    labelled export read other grasps than the import stores."""
    import json
    import sqlite3

    from planner import api
    from planner.calibration import labels
    from planner.plan.sweep import SweepSettings
    from tests.datasets.support import export

    db = tmp_path / "b.db"
    api.generate(["box"], "barrett", db_path=db, workers=1,
                 settings=SweepSettings(approaches=2, rolls=1, standoffs=(0.04,), preshapes=("pinch",)))
    path = export(db, "acronym", tmp_path / "out") / "box__barrett.h5"
    code, _, err = grasp("import", str(path), "--rescore", "--db", str(tmp_path / "re.db"), "--workers", "1")
    assert code == 0, err
    conn = sqlite3.connect(tmp_path / "re.db")
    query = "SELECT candidate, preshape, open_joints, epsilon FROM grasps ORDER BY candidate"
    imported = conn.execute(query).fetchall()
    assert imported and {r[1] for r in imported} == {"pinch"}
    assert all(json.loads(r[2])["bh_j11_joint"] == pytest.approx(1.5708) for r in imported)  # not the wrap's 0
    got = labels.labelled([path], poses=None, workers=1)
    assert got.table["epsilon"].tolist() == [r[3] for r in imported]


def test_re_scoring_on_two_workers_pairs_the_same_labels_as_on_one(tmp_path):
    """`grasp calibrate` re-scores on every core by default (as `import`, `generate` and `validate` do): the
    table it fits on must not depend on how many workers closed the poses."""
    from planner import api
    from planner.calibration import labels
    from planner.plan.sweep import SweepSettings
    from tests.datasets.support import export

    db = tmp_path / "b.db"
    api.generate(["box"], "panda", db_path=db, workers=1,
                 settings=SweepSettings(approaches=4, rolls=2, standoffs=(0.0,)))
    path = export(db, "acronym", tmp_path / "out") / "box__panda.h5"
    one = labels.labelled([path], poses=None, workers=1).table
    two = labels.labelled([path], poses=None, workers=2).table
    assert len(one["epsilon"]) > 4 and one.keys() == two.keys()
    for key in one:
        a, b = np.asarray(one[key]), np.asarray(two[key])
        same = np.array_equal(a, b, equal_nan=a.dtype.kind == "f")
        assert same, key


def test_calibrate_uses_every_core_by_default():
    from planner import api
    from planner.cli.calibrate import calibrate

    option = next(p for p in calibrate.params if p.name == "workers")
    assert option.default == api.default_workers()
