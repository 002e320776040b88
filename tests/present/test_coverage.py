"""``grasp report`` prints how much of each object's surface its top grasps cover."""

from __future__ import annotations

import re
from pathlib import Path

from planner import api
from tests.helpers import grasp


def test_report_prints_coverage(validated_db: Path, tmp_path: Path) -> None:
    code, out, err = grasp("report", "--db", str(validated_db), "--out", str(tmp_path / "r.html"))
    assert code == 0, err
    lines = [line for line in out.splitlines() if line.startswith("coverage ")]
    assert {line.split()[1].rstrip(":") for line in lines} == {"box/panda", "sphere/panda"}
    for line in lines:
        ranked, apart = (float(v) for v in re.findall(r"([\d.]+)% ", line))
        assert 0 < ranked <= 100 and 0 < apart <= 100


def test_more_grasps_cover_more(validated_db: Path) -> None:
    few = {(c.object, c.hand): c.ranked for c in api.coverage(validated_db, top=1)}
    many = {(c.object, c.hand): c.ranked for c in api.coverage(validated_db, top=10)}
    assert few.keys() == many.keys()
    assert all(few[k] <= many[k] for k in few)
