import sqlite3
from pathlib import Path

import pytest

from planner import api
from planner.db.lock import writer_lock
from planner.db.ranking import RankingRule
from planner.db.schema import SCHEMA_VERSION
from planner.db.store import open_db
from planner.errors import DatabaseError
from planner.plan.sweep import SweepSettings

SMALL = SweepSettings(approaches=4, rolls=2, preshapes=("wide",))


@pytest.fixture(scope="module")
def box_db(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("db") / "g.db"
    api.generate(["box"], "panda", db_path=path, settings=SMALL, seed=3)
    return path


def rows(path: Path) -> list[tuple]:
    with sqlite3.connect(path) as conn:
        return conn.execute("SELECT object, preshape, candidate, pose, epsilon, rank, score, reachability,"
                            " force_closure FROM grasps ORDER BY id").fetchall()


def test_generate_writes_ranked_grasps(box_db: Path) -> None:
    got = rows(box_db)
    assert got, "no grasps written"
    ranks = sorted(r[5] for r in got)
    assert ranks == list(range(1, len(got) + 1))
    by_rank = sorted(got, key=lambda r: r[5])
    assert [r[6] for r in by_rank] == sorted((r[6] for r in got), reverse=True)
    for *_, eps, _rank, score, reach, fc in got:
        expected = eps * (0.5 + 0.5 * reach) if fc else 0.0
        assert score == pytest.approx(expected)
        assert (reach is not None) == bool(fc)  # reachability is computed for force-closure grasps


def test_changing_the_rule_rescores_everything(box_db: Path, tmp_path: Path) -> None:
    import shutil

    copy = tmp_path / "copy.db"
    shutil.copy(box_db, copy)
    with open_db(copy) as db:
        assert db.apply_rule(RankingRule(reach_weight=0.0))
        assert not db.apply_rule(RankingRule(reach_weight=0.0))
    got = rows(copy)
    assert all(score == pytest.approx(eps if fc else 0.0) for *_, eps, _r, score, _reach, fc in got)
    by_rank = sorted(got, key=lambda r: r[5])
    assert [r[6] for r in by_rank] == sorted((r[6] for r in got), reverse=True)


def test_rerun_adds_nothing(box_db: Path) -> None:
    before = rows(box_db)
    summary = api.generate(["box"], "panda", db_path=box_db, settings=SMALL, seed=3)
    assert summary.skipped == 1 and summary.units == 0
    assert rows(box_db) == before


def test_same_seed_same_grasps(box_db: Path, tmp_path: Path) -> None:
    other = tmp_path / "again.db"
    api.generate(["box"], "panda", db_path=other, settings=SMALL, seed=3)
    assert rows(other) == rows(box_db)


def test_wal_mode_and_integrity(box_db: Path) -> None:
    with sqlite3.connect(box_db) as conn:
        assert conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    assert api.check_db(box_db) == []


def test_not_sqlite_is_refused_and_untouched(tmp_path: Path) -> None:
    path = tmp_path / "notes.db"
    path.write_text("my precious notes")
    with pytest.raises(DatabaseError, match="not an SQLite database"):
        open_db(path)
    assert path.read_text() == "my precious notes"


def test_foreign_sqlite_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "other.db"
    with sqlite3.connect(path) as conn:
        conn.execute("CREATE TABLE t (x)")
    with pytest.raises(DatabaseError, match="not a grasp database"):
        open_db(path)


def test_newer_schema_refuses_politely(tmp_path: Path) -> None:
    path = tmp_path / "new.db"
    open_db(path).close()
    with sqlite3.connect(path) as conn:
        conn.execute("UPDATE meta SET value = ? WHERE key = 'schema_version'", (str(SCHEMA_VERSION + 1),))
    with pytest.raises(DatabaseError, match="newer than this planner"):
        open_db(path)


def test_best_on_missing_db_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(DatabaseError, match="no such database"):
        api.best("box", "panda", db_path=tmp_path / "none.db")


def test_second_writer_refuses(box_db: Path) -> None:
    with writer_lock(box_db), pytest.raises(DatabaseError, match="another `grasp generate`"):
        api.generate(["box"], "panda", db_path=box_db, settings=SMALL, seed=4)
