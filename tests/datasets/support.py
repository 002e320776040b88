"""Builders and named tolerances of the dataset tests."""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path

import numpy as np
from helpers import grasp

from planner.db.ranking import RankingRule

#: The database keeps poses to 7 decimals; rebuilding one from Euler angles
#: re-orthonormalises the rounded rotation, which moves it by about that much.
ROUNDED_TOL = 1e-6
#: success does not weigh in, so the 'dropped' grasp keeps rank 1
SAME_ORDER_RULE = RankingRule(success_weight=0.0)


def export(db: Path, fmt: str, out: Path, *extra: str) -> Path:
    code, _, err = grasp("export", "--db", str(db), "--format", fmt, "--out", str(out), "--quiet", *extra)
    assert code == 0, err
    return out


def source_rows(db: Path, obj: str, where: str = "1") -> list[sqlite3.Row]:
    conn = sqlite3.connect(db)
    conn.row_factory = sqlite3.Row
    return conn.execute(f"SELECT * FROM grasps WHERE object = ? AND {where} ORDER BY rank, id", (obj,)).fetchall()


def pose(row: sqlite3.Row) -> np.ndarray:
    return np.array(json.loads(row["pose"])).reshape(4, 4)
