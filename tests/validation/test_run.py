"""Running validation over a database: results stored, grasps re-ranked."""

from __future__ import annotations

import shutil
import sqlite3
from pathlib import Path

import pytest

from planner.db.ranking import RankingRule, rule_measures
from planner.db.store import open_db
from planner.errors import InputError
from planner.validation.run import validate


def test_validate_stores_trials_and_reranks(validated_db: Path) -> None:
    with sqlite3.connect(validated_db) as conn:
        rows = conn.execute("SELECT g.score, g.epsilon, g.reachability, v.success, r.samples FROM grasps g "
                            "JOIN validation v ON v.grasp_id = g.id JOIN robust r ON r.grasp_id = g.id").fetchall()
        ranks = conn.execute("SELECT object, rank, score FROM grasps ORDER BY object, rank").fetchall()
    assert len(rows) == 6
    with open_db(validated_db, create=False, readonly=True) as db:
        validated = db.validated()
    analytic = RankingRule().analytic(rule_measures(validated))  # the default rule: reach 0.5, success 1
    assert len(validated) == 6 and all(g.measures is not None for g in validated)
    for g, a in zip(validated, analytic):
        assert g.robust is not None and g.robust.samples == 2
        assert g.score == pytest.approx(a * (0.5 + 0.5 * g.reachability) * float(g.validation.success))
    assert all(score == 0 for score, _, _, ok, _ in rows if not ok)  # a failed trial zeroes the score
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
