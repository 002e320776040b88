"""Running validation over a database: results stored, grasps re-ranked."""

from __future__ import annotations

import shutil
import sqlite3
from pathlib import Path

import pytest

from planner.errors import InputError
from planner.validation.run import validate


def test_validate_stores_trials_and_reranks(validated_db: Path) -> None:
    with sqlite3.connect(validated_db) as conn:
        rows = conn.execute("SELECT g.score, g.epsilon, g.reachability, v.success, r.samples FROM grasps g "
                            "JOIN validation v ON v.grasp_id = g.id JOIN robust r ON r.grasp_id = g.id").fetchall()
        ranks = conn.execute("SELECT object, rank, score FROM grasps ORDER BY object, rank").fetchall()
    assert len(rows) == 6
    for score, eps, reach, success, samples in rows:
        assert samples == 2
        assert score == pytest.approx(eps * (0.5 + 0.5 * reach) * float(success))
    for obj in ("box", "sphere"):
        scores = [s for o, _, s in ranks if o == obj]
        assert scores == sorted(scores, reverse=True)


def test_unknown_object_and_bad_top_are_refused_before_work(validated_db: Path, tmp_path: Path) -> None:
    copy = tmp_path / "v.db"
    shutil.copy(validated_db, copy)
    with pytest.raises(InputError, match="no grasps of object 'teapot'.*objects: box, sphere"):
        validate(copy, objects=["teapot"])
    with pytest.raises(InputError, match="--top must be at least 1"):
        validate(copy, top=0)
