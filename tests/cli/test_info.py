"""``grasp hands``, ``grasp objects``, ``grasp db check``."""

from __future__ import annotations

import shutil
import sqlite3
from pathlib import Path

from helpers import grasp


def test_lists() -> None:
    code, out, _ = grasp("hands")
    assert code == 0 and "panda" in out
    code, out, _ = grasp("objects")
    assert code == 0 and all(n in out for n in ("mug", "duck", "teddy", "bunny", "box", "cylinder", "sphere"))


def test_db_check(box_db: Path) -> None:
    code, out, _ = grasp("db", "check", "--db", str(box_db))
    assert code == 0 and "ok" in out


def test_db_check_reports_corruption(box_db: Path, tmp_path: Path) -> None:
    code, _, _ = grasp("db", "check", "--db", str(box_db))
    assert code == 0
    broken = tmp_path / "broken.db"
    shutil.copy(box_db, broken)
    with sqlite3.connect(broken) as conn:
        conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    data = bytearray(broken.read_bytes())
    page = 4096
    for i in range(2 * page + 100, min(len(data), 5 * page), 7):
        data[i] ^= 0x5A
    broken.write_bytes(bytes(data))
    code, _, err = grasp("db", "check", "--db", str(broken))
    assert code == 3 and "Traceback" not in err


def test_one_hand_in_detail() -> None:
    code, out, _ = grasp("hands", "barrett")
    assert code == 0 and "root link: bh_palm" in out and "joint bh_j32_joint (revolute)" in out
    assert "preshape wrap tags=power" in out
