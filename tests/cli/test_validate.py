"""``grasp validate`` and ``grasp report`` on the command line."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from helpers import grasp


def test_validate_json_summary_and_failures(validated_db: Path, tmp_path: Path) -> None:
    copy = tmp_path / "v.db"
    shutil.copy(validated_db, copy)
    code, out, err = grasp("validate", "--db", str(copy), "--object", "box", "--top", "1", "--robust", "0",
                           "--workers", "1", "--json")
    assert code == 0, err
    summary = json.loads(out)
    assert summary["grasps"] == 1 and summary["successes"] in (0, 1) and summary["failed"] == {}


def test_report_prints_the_file_it_wrote(validated_db: Path, tmp_path: Path) -> None:
    code, out, err = grasp("report", "--db", str(validated_db), "--out", str(tmp_path / "r.html"))
    assert code == 0 and out.strip() == str(tmp_path / "r.html"), err
