"""The writer lock: a second writer of one database refuses at once."""

from __future__ import annotations

import subprocess
import time
from pathlib import Path

import pytest
from helpers import reference_command

from planner import api
from planner.db.lock import writer_lock
from planner.db.store import open_db
from planner.errors import DatabaseError
from planner.plan.sweep import SweepSettings

SMALL = SweepSettings(approaches=4, rolls=2, preshapes=("wide",))


def test_second_writer_refuses(tmp_path: Path) -> None:
    db = tmp_path / "g.db"
    with writer_lock(db), pytest.raises(DatabaseError, match="another `grasp generate`"):
        api.generate(["box"], "panda", db_path=db, settings=SMALL, seed=4)
    with writer_lock(db):  # released: a writer may take it again
        pass


def test_two_writers_second_refuses(tmp_path: Path) -> None:
    db = tmp_path / "two.db"
    first = subprocess.Popen(reference_command(db), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.time() + 60
        while not Path(str(db) + ".lock").exists() and time.time() < deadline:
            time.sleep(0.05)
        time.sleep(0.5)
        second = subprocess.run(reference_command(db), capture_output=True, text=True)
        if first.poll() is None:
            assert second.returncode == 3
            assert "another `grasp generate` is writing" in second.stderr
    finally:
        first.wait()
    assert open_db(db, create=False, readonly=True).integrity_check() == []
