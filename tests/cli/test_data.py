"""``grasp export`` and ``grasp import`` on the command line."""

from __future__ import annotations

import json
from pathlib import Path

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
