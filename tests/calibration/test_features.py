"""The measure table: the same model inputs from grasp records and from stored columns (local_sdf's cells
too, the fill where it was not measured); contact depth."""

from __future__ import annotations

import json
import sqlite3
from dataclasses import replace
from pathlib import Path

import numpy as np
from helpers import assert_close, made_up

from planner.calibration import features
from planner.db.ranking import RankingRule
from planner.db.store import UnitRow, open_db
from planner.plan.measures import Measures

#: Stored vectors keep 7 decimals (0.1 um).
STORED_TOL = 1e-6


def test_stored_columns_give_the_measure_table_of_the_records(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    # local_sdf measured on some grasps (its cells: what the trees read), not on the others (NULL: the fill)
    local = [np.round(rng.uniform(-0.02, 0.02, 75), 4) if i % 2 else None for i in range(4)]
    grasps = [replace(made_up(i, 0.01 * i, fc=i % 2 == 0), measures=Measures(2.0 * i, 3.0 * i, 0.003, np.inf,
                                                                              0.9, (), local_sdf=local[i]))
              for i in range(4)]
    unit = UnitRow("thing", "panda", "h" * 16, json.dumps({}), 5, 0, None)
    with open_db(tmp_path / "g.db") as db:
        db.write_unit(unit, None, grasps, RankingRule())
    conn = sqlite3.connect(tmp_path / "g.db")
    conn.row_factory = sqlite3.Row
    rows = conn.execute("SELECT * FROM grasps ORDER BY candidate").fetchall()
    col = {k: [r[k] for r in rows] for k in rows[0].keys()}
    names = [*features.FEATURES, *features.PRODUCTS]
    # an untouched margin: inf in the record, NULL in the store; both are the cap as model inputs
    assert_close(features.design(features.of_columns(col), names), features.design(features.of_grasps(grasps), names),
                 STORED_TOL)
    cells = features.design(features.of_columns(col), features.LOCAL)
    assert_close(cells[1], local[1], 0.0)
    assert_close(cells[0], np.full(75, features.FILL["local_sdf_00"]), 0.0)


def test_contact_depth_is_the_mean_distance_along_the_approach_and_moves_with_the_hand() -> None:
    pose = np.eye(4)[None].repeat(2, axis=0)
    pose[1, :3, 3] = [0.0, 0.0, -0.01]  # the hand 1 cm further back along +z
    approach = np.array([[0.0, 0.0, 1.0]] * 2)
    points = [np.array([[0.01, 0.0, 0.10], [-0.01, 0.0, 0.12]])] * 2
    assert_close(features.contact_depth(pose, approach, points), [0.11, 0.12])
    assert np.isnan(features.contact_depth(pose[:1], approach[:1], [np.zeros((0, 3))])[0])
