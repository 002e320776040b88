"""GraspGen JSON: the ACRONYM content, NaN as null."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from helpers import assert_close

from tests.datasets.support import export

h5py = pytest.importorskip("h5py")
pq = pytest.importorskip("pyarrow.parquet")


def test_graspgen_json_has_the_acronym_content(db: Path, tmp_path: Path) -> None:
    export(db, "acronym", tmp_path / "h5", "--object", "box")
    export(db, "graspgen", tmp_path / "json", "--object", "box")
    data = json.loads((tmp_path / "json" / "box__panda.json").read_text())
    with h5py.File(tmp_path / "h5" / "box__panda.h5", "r") as f:
        assert_close(np.array(data["grasps"]["transforms"]), f["grasps/transforms"][()])
        assert data["grasps"]["object_in_gripper"] == list(f["grasps/qualities/flex/object_in_gripper"][()])
        assert data["grasps"]["epsilon"] == list(f["grasps/qualities/epsilon"][()])
        assert data["object"]["scale"] == f["object/scale"][()] and data["object"]["file"] == "primitive:box"
    assert data["gripper"]["type"] == "panda" and data["gripper"]["configuration"] == [pytest.approx(0.08)]
    assert data["grasps"]["simulated_success"][:3] == [0, 1, -1]
    assert data["grasps"]["robust_epsilon_mean"][2] is None  # NaN -> null
    assert {"point", "normal", "link"} <= set(data["grasps"]["contacts"][0][0])
