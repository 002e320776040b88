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
    assert "random_000 .. random_999  mass 0.100 kg  friction 0.50" in out  # the README's weight points here


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


def test_a_damaged_page_is_said_to_be_damage_not_a_full_disk(box_db: Path, tmp_path: Path) -> None:
    """One page of the grasps table zeroed: `db check` lists the problems on stdout and fails with one line and
    the database's exit code 3 (it was 1, the problems on stderr); a write names the damage (it said the disk
    was full: SQLite's "database disk image is malformed")."""
    from helpers import damaged

    from planner.db.failures import write_failed

    broken = damaged(box_db, tmp_path / "broken.db")
    code, out, err = grasp("db", "check", "--db", str(broken))
    assert code == 3 and len(err.strip().splitlines()) == 1 and "integrity check failed" in err and out.strip(), err
    line = write_failed(broken, sqlite3.DatabaseError("database disk image is malformed"), 4)
    assert "the database file is damaged" in line and "disk is full" not in line
