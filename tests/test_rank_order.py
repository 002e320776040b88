"""Every reader follows the rank order (planner.db.ranking.FIRST): a grasp force closure only once squeezed whose
squeeze's end the sweep stored beside it ranks after every grasp that ranks first, in ``grasp best``, ``grasp show``,
the report's analytic order and every export's rank column; a lossless import of an export ranks as its source."""

from __future__ import annotations

import csv
import json
import sqlite3
from pathlib import Path

import pytest
import yaml
from helpers import grasp

from planner import api
from planner.db.ranking import FIRST_SQL, RankingRule
from planner.db.store import open_db
from planner.plan.sweep import SweepSettings

#: The mug, 60 antipodal points and 2 rolls: 27 grasps, two squeezes' ends among them (seed 3).
MUG = SweepSettings(approaches=60, rolls=2, reach_placements=0)


@pytest.fixture(scope="module")
def mug_db(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("rank") / "mug.db"
    summary = api.generate(["mug"], "panda", db_path=path, settings=MUG, seed=3, workers=1)
    assert not summary.failed
    return path


def stood_for(db: Path) -> tuple[int, set[int]]:
    """(how many grasps rank first, the ranks of the grasps whose squeeze's end is stored beside them)."""
    with sqlite3.connect(db) as conn:
        first = conn.execute(f"SELECT SUM({FIRST_SQL}) FROM grasps").fetchone()[0]
        parents = {r for (r,) in conn.execute(
            "SELECT p.rank FROM grasps p JOIN grasps e ON e.unit_id = p.unit_id AND e.candidate = p.candidate AND "
            "e.squeezed_from_turn IS NOT NULL WHERE p.squeezed_from_turn IS NULL")}
    return first, parents


def test_the_sweeps_parents_rank_after_every_grasp_that_ranks_first(mug_db: Path) -> None:
    """Before, most ranked beside their ends, among the force-closure grasps."""
    first, parents = stood_for(mug_db)
    assert parents and min(parents) > first
    best = json.loads(grasp("best", "mug", "--hand", "panda", "--db", str(mug_db), "--top", str(first), "--json")[1])
    assert len(best) == first and all(g["force_closure"] or g["squeezed_force_closure"] for g in best)
    assert not {g["rank"] for g in best} & parents
    shown = api.show("mug", "panda", mug_db.parent / "s.png", db_path=mug_db, rank=min(parents))
    assert [g.end_kept for g in shown] == [True] and not shown[0].force_closure


def test_the_reports_analytic_order_puts_them_after_the_grasps_that_rank_first(mug_db: Path) -> None:
    from planner.present.report import analytic_order

    with open_db(mug_db, create=False, readonly=True) as db:
        sweep = [g for batch in db.grasp_batches("mug", "panda") for g in batch]
    where = {i: k for k, i in enumerate(analytic_order(RankingRule(), sweep))}
    first, _ = stood_for(mug_db)
    assert all(where[g.id] >= first for g in sweep if g.end_kept)
    assert sorted(where[g.id] for g in sweep if g.rank <= first) == list(range(first))  # type: ignore[operator]


def test_every_exports_rank_follows_the_order(mug_db: Path, tmp_path: Path) -> None:
    """CSV's rank column, MoveIt's ids in file order, ACRONYM's qualities/rank; its lossless import ranks alike."""
    import h5py

    first, parents = stood_for(mug_db)
    for fmt in ("csv", "moveit", "acronym"):
        code, _, err = grasp("export", "--db", str(mug_db), "--format", fmt, "--out", str(tmp_path / fmt), "--quiet")
        assert code == 0, err
    with open(tmp_path / "csv" / "grasps.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    ends = {(r["unit_id"], r["candidate"]) for r in rows if r["squeezed_from_turn"] not in ("", "nan")}
    kept = [(r["unit_id"], r["candidate"]) in ends and r["squeezed_from_turn"] in ("", "nan") for r in rows]
    assert {int(r["rank"]) for r, k in zip(rows, kept) if k} == parents
    assert sum(r["force_closure"] == "1" or (r["squeezed_force_closure"] == "1" and not k)
               for r, k in zip(rows, kept)) == first < min(parents)
    (moveit,) = (tmp_path / "moveit").glob("**/*.yaml")
    ranks = [int(m["id"].rsplit("/", 1)[1]) for m in yaml.safe_load(moveit.read_text())]
    assert ranks == list(range(1, len(ranks) + 1))
    (h5,) = (tmp_path / "acronym").glob("**/*.h5")
    with h5py.File(h5) as f:
        g = f["grasps"]
        rank, turned, candidate = g["qualities/rank"][()], g["squeezed_from_turn"][()], g["candidate"][()]
    ends = {int(c) for c, t in zip(candidate, turned) if t == t}
    assert {int(r) for r, c, t in zip(rank, candidate, turned) if t != t and int(c) in ends} == parents
    imported = tmp_path / "imported.db"
    code, _, err = grasp("import", str(h5), "--db", str(imported))
    assert code == 0, err
    assert stood_for(imported) == (first, parents)


def test_an_import_of_two_seeds_sweeps_keeps_each_end_beside_its_parent(tmp_path: Path) -> None:
    """Two sweeps of one object (seeds 3 and 4) number their candidates alike: the file's candidates do not tell
    its grasps apart, the import numbers them by row, and each end still takes its parent's number (its seed and
    candidate find it), so its lossless import ranks as its source (before: every parent ranked first again)."""
    db = tmp_path / "two.db"
    for seed in (3, 4):
        assert not api.generate(["mug"], "panda", db_path=db, settings=MUG, seed=seed, workers=1).failed
    with sqlite3.connect(db) as conn:
        (shared,) = conn.execute("SELECT COUNT(*) FROM grasps a JOIN grasps b ON a.candidate = b.candidate AND "
                                 "a.seed < b.seed").fetchone()
    first, parents = stood_for(db)
    assert shared and parents
    code, _, err = grasp("export", "--db", str(db), "--format", "acronym", "--out", str(tmp_path / "out"), "--quiet")
    assert code == 0, err
    imported = tmp_path / "imported.db"
    code, _, err = grasp("import", str(tmp_path / "out" / "mug__panda.h5"), "--db", str(imported))
    assert code == 0, err
    assert stood_for(imported) == (first, parents)
