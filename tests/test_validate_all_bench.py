"""bench/validate_all.py: tuning objects only; its dump compares every stored row."""

import sqlite3
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))

import validate_all  # noqa: E402


def test_held_out_objects_are_refused_before_any_work(tmp_path: Path) -> None:
    db = tmp_path / "v.db"
    for names in (["random_000"], ["random_002", "duck"], ["random_115"]):  # held_out, held_out, held_out_4
        with pytest.raises(SystemExit, match="not tuning objects"):
            validate_all.database(db, names)
    assert not db.exists()


def test_the_dump_holds_every_row_but_meta_and_units(tmp_path: Path) -> None:
    db = tmp_path / "d.db"
    with sqlite3.connect(db) as conn:
        for table in ("grasps", "meta", "units", "mujoco"):
            conn.execute(f"CREATE TABLE {table} (a, b)")
            conn.execute(f"INSERT INTO {table} VALUES (1, 0.1)")
    out = tmp_path / "dump.txt"
    validate_all.dump(db, out)
    assert out.read_text().splitlines() == ["grasps (1, 0.1)", "mujoco (1, 0.1)"]
