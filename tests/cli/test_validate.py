"""``grasp validate`` and ``grasp report`` on the command line."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from helpers import FAST, grasp


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
    assert code == 0 and out.splitlines()[0] == str(tmp_path / "r.html"), err
    assert all(line.startswith("coverage ") for line in out.splitlines()[1:])


def test_validate_all_force_closure_tests_exactly_the_force_closure_grasps(tmp_path: Path) -> None:
    import sqlite3

    copy = tmp_path / "v.db"
    code, _, err = grasp("generate", "box", "--hand", "panda", "--db", str(copy), "--sampler", "surface", "--quiet",
                         *FAST)
    assert code == 0, err
    with sqlite3.connect(copy) as conn:
        total, closure = conn.execute("SELECT COUNT(*), SUM(force_closure) FROM grasps").fetchone()
    assert 0 < closure < total, "the box database should hold grasps of both kinds"
    code, out, err = grasp("validate", "--db", str(copy), "--all", "--force-closure", "--robust", "0",
                           "--workers", "1", "--json")
    assert code == 0, err
    assert json.loads(out)["grasps"] == closure
    with sqlite3.connect(copy) as conn:
        tested = conn.execute("SELECT g.force_closure FROM validation v JOIN grasps g ON g.id = v.grasp_id").fetchall()
    assert len(tested) == closure and all(fc == 1 for (fc,) in tested)
