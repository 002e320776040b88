"""GraspGen JSON: the ACRONYM content, NaN as null."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np
from helpers import assert_close

from tests.datasets.support import export


def test_graspgen_json_has_the_acronym_content(db: Path, tmp_path: Path) -> None:
    export(db, "acronym", tmp_path / "h5", "--object", "box")
    export(db, "graspgen", tmp_path / "json", "--object", "box")
    data = json.loads((tmp_path / "json" / "grasp_data" / "panda" / "box.json").read_text())
    with h5py.File(tmp_path / "h5" / "box__panda.h5", "r") as f:
        assert_close(np.array(data["grasps"]["transforms"]), f["grasps/transforms"][()])
        assert data["grasps"]["object_in_gripper"] == [v == 1 for v in f["grasps/qualities/flex/object_in_gripper"]]
        assert data["grasps"]["epsilon"] == list(f["grasps/qualities/epsilon"][()])
        assert data["object"]["scale"] == f["object/scale"][()] == 1.0
        assert data["object"]["file"] == f["object/file"][()].decode() == "meshes/box.obj"
        assert data["gripper"]["configuration"] == list(f["gripper/configuration"][()]) == [0.04]
    assert data["gripper"]["type"] == "panda" and data["object"]["source"] == "primitive:box"
    assert {type(v) for v in data["grasps"]["object_in_gripper"] + data["grasps"]["force_closure"]} == {bool}
    assert data["grasps"]["simulated_success"][:3] == [0, 1, -1]
    assert data["grasps"]["robust_epsilon_mean"][2] is None  # NaN -> null
    assert {"point", "normal", "link"} <= set(data["grasps"]["contacts"][0][0])


def test_a_killed_exports_spool_is_cleared_by_the_next(db: Path, tmp_path: Path) -> None:
    """A kill -9 during a GraspGen export left its spool folder (a random name, never cleared); the spool is named
    after its file, so the next export of that file clears it, and a finished export leaves none."""
    folder = tmp_path / "json" / "grasp_data" / "panda"
    folder.mkdir(parents=True)
    left = folder / ".box.json.spool"
    left.mkdir()
    (left / "0.part").write_text("[1, 2")  # what a killed export leaves
    export(db, "graspgen", tmp_path / "json", "--object", "box")
    assert sorted(p.name for p in folder.iterdir()) == ["box.json", "map_uuid_to_path.json"]
