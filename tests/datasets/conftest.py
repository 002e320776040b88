"""The database every dataset test exports: box and sphere for the Panda."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import pytest

from planner import api
from planner.db.store import open_db
from planner.plan.sweep import SweepSettings
from tests.datasets.support import SAME_ORDER_RULE

SMALL = SweepSettings(approaches=6, rolls=2, preshapes=("wide",), reach_placements=1)


@pytest.fixture(scope="package")
def db(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """box and sphere for the Panda; the two best box grasps carry fake
    validation and robust rows (the best one 'dropped' despite force closure)."""
    path = tmp_path_factory.mktemp("export") / "g.db"
    summary = api.generate(["box", "sphere"], "panda", db_path=path, settings=SMALL, workers=1)
    assert not summary.failed and summary.force_closure > 0
    with sqlite3.connect(path) as conn:
        ids = [r[0] for r in conn.execute("SELECT id FROM grasps WHERE object = 'box' ORDER BY rank LIMIT 2")]
        for gid, success in zip(ids, (0, 1)):
            conn.execute("INSERT INTO validation (grasp_id, success, fingers_in_contact, closing_linear,"
                         " closing_angular, shaking_linear, shaking_angular, seed, settings)"
                         " VALUES (?, ?, 2, 0.001, 0.01, 0.002, 0.02, 0, '{}')", (gid, success))
            conn.execute("INSERT INTO robust VALUES (?, 0.05, 0.02, 25, 0, '{}')", (gid,))
    with open_db(path) as handle:  # a rule under which the fake validation leaves the ranking as it was
        handle.apply_rule(SAME_ORDER_RULE, force=True)
    return path
