"""``grasp export`` and ``grasp import`` on the command line."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from helpers import grasp


def test_export_summary_and_import_json(box_db: Path, tmp_path: Path) -> None:
    code, out, err = grasp("export", "--db", str(box_db), "--format", "acronym", "--out", str(tmp_path), "--json")
    assert code == 0, err
    summary = json.loads(out)
    assert summary["format"] == "acronym" and summary["files"] == [str(tmp_path / "box__panda.h5")]
    assert summary["meshes"] == [str(tmp_path / "meshes" / "box.obj")]
    code, out, err = grasp("import", str(tmp_path / "box__panda.h5"), "--db", str(tmp_path / "i.db"), "--json")
    assert code == 0, err
    [result] = json.loads(out)
    assert (result["object"], result["hand"], result["grasps"], result["skipped"]) == \
        ("box", "panda", summary["grasps"], False)


def test_an_export_says_where_labels_are_the_force_closure_flag(box_db: Path, tmp_path: Path,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """A hand without a p_hold model (here the Panda: the tests run without the shipped models) labels its
    untried grasps by the force-closure flag, which is not a success label: the export says so."""
    code, _, err = grasp("export", "--db", str(box_db), "--format", "csv", "--out", str(tmp_path / "a"))
    assert code == 0 and "note: hand 'panda' has no calibrated p_hold model" in err, err
    code, _, err = grasp("export", "--db", str(box_db), "--format", "csv", "--out", str(tmp_path / "b"),
                         "--label", "force_closure")
    assert code == 0 and "note:" not in err, err  # asked for by name
    from planner.calibration.model import SHIPPED_ENV

    monkeypatch.setenv(SHIPPED_ENV, "1")
    code, out, err = grasp("export", "--db", str(box_db), "--format", "csv", "--out", str(tmp_path / "c"), "--json")
    assert code == 0 and json.loads(out)["notes"] == [], err


def test_export_and_validate_take_an_objects_mesh_file_as_best_does(tmp_path: Path) -> None:
    """`--object mine/brick.stl` was refused by export and validate ("no grasps of object 'mine/brick.stl'")
    while best and show took the file's path."""
    import trimesh

    mesh = tmp_path / "mine" / "brick.stl"
    mesh.parent.mkdir()
    trimesh.creation.box(extents=(0.05, 0.04, 0.03)).export(mesh)
    db = str(tmp_path / "g.db")
    code, _, err = grasp("generate", str(mesh), "--hand", "panda", "--db", db, "--approaches", "4", "--workers", "1")
    assert code == 0, err
    code, out, err = grasp("export", "--db", db, "--format", "csv", "--out", str(tmp_path / "out"), "--object",
                           str(mesh), "--json")
    assert code == 0, err
    assert json.loads(out)["grasps"] > 0
    code, out, err = grasp("validate", "--db", db, "--object", str(mesh), "--top", "1", "--robust", "0", "--json",
                           "--workers", "1")
    assert code == 0, err
    assert json.loads(out)["grasps"] == 1


def test_an_imported_objects_name_is_where_the_help_says(box_db: Path, tmp_path: Path) -> None:
    """`grasp import --help` said the object's name defaults to "the file's object/name or object/file"; a file
    without object/name is named after the .h5 file (scan7), not its object/file (box.obj). The help says so."""
    import h5py

    code, _, err = grasp("export", "--db", str(box_db), "--format", "acronym", "--out", str(tmp_path), "--quiet")
    assert code == 0, err
    scan = (tmp_path / "box__panda.h5").rename(tmp_path / "scan7.h5")
    with h5py.File(scan, "r+") as f:
        del f["object/name"]
    code, out, err = grasp("import", str(scan), "--db", str(tmp_path / "i.db"), "--json")
    assert code == 0 and json.loads(out)[0]["object"] == "scan7", err
    code, out, _ = grasp("import", "--help")
    assert "else by the file's name without .h5" in " ".join(out.split())
