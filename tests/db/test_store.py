"""The store: generate writes ranked grasps; units are written whole and
read back as the same records; validation re-scores with the rule."""

from __future__ import annotations

import json
import sqlite3
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from helpers import assert_close, damaged, made_up

from planner import api
from planner.db.ranking import RankingRule, rule_measures
from planner.db.store import UnitRow, Validated, open_db
from planner.errors import DatabaseError
from planner.plan.measures import MIN_RESISTANCE, Measures
from planner.plan.sweep import SweepSettings
from planner.record.grasp import RobustEpsilon, Trial

SMALL = SweepSettings(approaches=4, rolls=2, preshapes=("wide",))
#: Stored vectors keep 7 decimals.
STORED_TOL = 5e-8


@pytest.fixture(scope="module")
def seeded_db(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("db") / "g.db"
    api.generate(["box"], "panda", db_path=path, settings=SMALL, seed=3)
    return path


def rows(path: Path) -> list[tuple]:
    with sqlite3.connect(path) as conn:
        return conn.execute("SELECT object, preshape, candidate, pose, epsilon, rank, score, reachability,"
                            " force_closure FROM grasps ORDER BY id").fetchall()


def records(path: Path) -> list:
    with open_db(path, create=False, readonly=True) as db:
        return [g for batch in db.grasp_batches("box", "panda") for g in batch]


def test_generate_writes_ranked_grasps_scored_by_the_rule_from_their_measures(seeded_db: Path) -> None:
    got = rows(seeded_db)
    assert got, "no grasps written"
    ranks = sorted(r[5] for r in got)
    assert ranks == list(range(1, len(got) + 1))
    by_rank = sorted(got, key=lambda r: r[5])
    assert [r[6] for r in by_rank] == sorted((r[6] for r in got), reverse=True)
    grasps = records(seeded_db)
    assert all(g.measures is not None for g in grasps)
    assert_close([g.score for g in grasps], RankingRule().scores(rule_measures(grasps)))
    for g in grasps:  # reachability is computed for grasps that are force closure or hold their weight
        assert (g.reachability is not None) == (g.force_closure or g.measures.resist_worst >= MIN_RESISTANCE)


def test_changing_the_rule_rescores_everything(seeded_db: Path, tmp_path: Path) -> None:
    import shutil

    copy = tmp_path / "copy.db"
    shutil.copy(seeded_db, copy)
    with open_db(copy) as db:
        assert db.apply_rule(RankingRule(reach_weight=0.0))
        assert not db.apply_rule(RankingRule(reach_weight=0.0))
    got = rows(copy)
    grasps = records(copy)
    assert_close([g.score for g in grasps], RankingRule(reach_weight=0.0).analytic(rule_measures(grasps)))
    by_rank = sorted(got, key=lambda r: r[5])
    assert [r[6] for r in by_rank] == sorted((r[6] for r in got), reverse=True)


def test_rerun_adds_nothing(seeded_db: Path) -> None:
    before = rows(seeded_db)
    summary = api.generate(["box"], "panda", db_path=seeded_db, settings=SMALL, seed=3)
    assert summary.skipped == 1 and summary.units == 0
    assert rows(seeded_db) == before


def test_same_seed_same_grasps(seeded_db: Path, tmp_path: Path) -> None:
    other = tmp_path / "again.db"
    api.generate(["box"], "panda", db_path=other, settings=SMALL, seed=3)
    assert rows(other) == rows(seeded_db)


def test_wal_mode_and_integrity(seeded_db: Path) -> None:
    with sqlite3.connect(seeded_db) as conn:
        assert conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    assert api.check_db(seeded_db) == []


def unit(error: str | None = None, chunk: int = 0) -> UnitRow:
    return UnitRow("thing", "panda", "h" * 16, json.dumps({"made": "up"}), 5, chunk, error, candidates=9,
                   rejected={"missed": 3}, seconds=0.5)


def test_a_unit_is_written_whole_and_read_back_as_the_same_records(tmp_path: Path) -> None:
    grasps = [made_up(0, 0.05, reach=0.5), made_up(1, 0.08, reach=None), made_up(2, 0.0, fc=False)]
    rule = RankingRule()
    with open_db(tmp_path / "g.db") as db:
        unit_id = db.write_unit(unit(), None, grasps, rule)
        assert db.units_done("panda", "h" * 16, 5) == {("thing", 0)}
        back = db.best("thing", "panda", 10)
        assert db.grasp_ids(unit_id) == {(g.candidate, False): g.id for g in back}
    assert [g.candidate for g in back] == [1, 0, 2]  # by score
    assert [g.rank for g in back] == [1, 2, 3]
    expected = rule.scores({"epsilon": [0.08, 0.05, 0.0], "force_closure": [1, 1, 0],
                            "reachability": [np.nan, 0.5, np.nan]})
    assert_close([g.score for g in back], expected)
    for g in back:
        original = grasps[g.candidate]
        assert_close(g.pose, original.pose, STORED_TOL)
        assert_close(g.approach_point, original.approach_point, STORED_TOL)
        assert g.contacts.json_text() == original.contacts.json_text()
        assert (len(g.contacts), g.contacts.touching) == (2, 2)
        assert (g.closed_joints, g.open_joints, g.width, g.seed, g.preshape) == ({"j": 0.02}, {"j": 0.04}, 0.04, 5,
                                                                                  "wide")
        assert (g.epsilon, g.force_closure, g.reachability) == (original.epsilon, original.force_closure,
                                                                original.reachability)
        assert g.unit_id == unit_id and g.validation is None and g.robust is None
    with sqlite3.connect(tmp_path / "g.db") as conn:
        row = conn.execute("SELECT status, candidates, grasps, force_closure, rejected FROM units").fetchone()
    assert row == ("done", 9, 3, 2, json.dumps({"missed": 3}, separators=(",", ":")))


def test_a_record_as_stored_is_what_the_store_gives_back_to_the_last_bit(tmp_path: Path) -> None:
    """Grasp.as_stored (what the settle is run on) rounds as the store does: the same floats, not just close."""
    rng = np.random.default_rng(4)
    grasps = []
    for i in range(3):
        g = made_up(i, 0.05)
        pose = np.eye(4)
        pose[:3, :3] = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        pose[:3, 3] = rng.normal(size=3) * 0.1
        points = rng.normal(size=(2, 3)) * 0.03
        grasps.append(replace(g, pose=pose, approach_point=rng.normal(size=3) * 0.05,
                              approach_dir=rng.normal(size=3), table_plane=np.r_[rng.normal(size=3), 0.012345678901],
                              contacts=type(g.contacts)(points, -points / np.linalg.norm(points, axis=1)[:, None],
                                                        ("left", "right"))))
    with open_db(tmp_path / "g.db") as db:
        db.write_unit(unit(), None, grasps, RankingRule())
        back = {g.candidate: g for g in db.best("thing", "panda", 10)}
    for g in grasps:
        mine, theirs = g.as_stored(), back[g.candidate]
        assert not np.array_equal(mine.pose, g.pose)  # the random pose has more than 7 decimals
        for name in ("pose", "approach_point", "approach_dir", "table_plane"):
            assert np.array_equal(getattr(mine, name), getattr(theirs, name)), name
        assert np.array_equal(mine.contacts.points, theirs.contacts.points)
        assert np.array_equal(mine.contacts.normals, theirs.contacts.normals)
        assert mine.contacts.links == theirs.contacts.links
        assert dict(mine.closed_joints) == dict(theirs.closed_joints) and mine.epsilon == theirs.epsilon


def test_writing_a_unit_again_replaces_it_and_a_failure_is_recorded(tmp_path: Path) -> None:
    with open_db(tmp_path / "g.db") as db:
        db.write_unit(unit(), None, [made_up(0, 0.05)], RankingRule())
        db.write_unit(unit(), None, [made_up(0, 0.05), made_up(1, 0.06)], RankingRule())
        db.write_unit(unit("Boom: simulator", chunk=1), None, [], RankingRule())
        assert len(db.best("thing", "panda", 10)) == 2
        assert db.units_done("panda", "h" * 16, 5) == {("thing", 0)}
    with sqlite3.connect(tmp_path / "g.db") as conn:
        assert conn.execute("SELECT chunk, status, error FROM units ORDER BY chunk").fetchall() == [
            (0, "done", None), (1, "failed", "Boom: simulator")]


def test_validation_results_rescore_with_the_rule(tmp_path: Path) -> None:
    rule = RankingRule(reach_weight=0.0, success_weight=1.0, robust_weight=0.5)
    with open_db(tmp_path / "g.db") as db:
        db.write_unit(unit(), None, [made_up(0, 0.05), made_up(1, 0.08), made_up(2, 0.02)], rule)
        ids = {g.candidate: g.id for g in db.best("thing", "panda", 10)}
        held = Trial(True, 2, 0.001, 0.01, 0.002, 0.02, "held")
        dropped = Trial(False, 1, 0.03, 0.2, 0.1, 0.5, "slipped")
        db.write_validation("thing", "panda", [
            Validated(ids[0], held, RobustEpsilon(0.04, 0.01, 4), 0, "{}", "{}"),
            Validated(ids[1], dropped, None, 0, "{}", "{}")], rule)
        back = {g.candidate: g for g in db.best("thing", "panda", 10)}
    assert back[0].validation == held and back[0].robust == RobustEpsilon(0.04, 0.01, 4)
    assert back[1].validation == dropped and back[1].robust is None and back[2].validation is None
    w = rule.eps_weight
    analytic = [1.0 + w * (0.5 * 0.05 + 0.5 * 0.01), 0.0, 1.0 + w * 0.02]  # no measures: hold = closure
    assert_close([back[c].score for c in (0, 1, 2)], analytic)
    assert [back[c].rank for c in (0, 2, 1)] == [1, 2, 3]  # the failed grasp, best by epsilon, scores 0


def test_a_mujoco_verdict_is_stored_apart_and_a_drop_in_either_protocol_counts(tmp_path: Path) -> None:
    # grasp 0: held in both; 1: held in PyBullet, dropped in MuJoCo; 2: MuJoCo only, held
    rule = RankingRule(reach_weight=0.0, success_weight=1.0)
    held = Trial(True, 2, 0.001, 0.01, 0.002, 0.02, "held")
    dropped = Trial(False, 1, 0.03, 0.2, 0.1, 0.5, "slipped")
    mj_held = Trial(True, 2, 0.004, 0.03, 0.006, 0.05, "held")
    with open_db(tmp_path / "g.db") as db:
        db.write_unit(unit(), None, [made_up(0, 0.05), made_up(1, 0.08), made_up(2, 0.02)], rule)
        ids = {g.candidate: g.id for g in db.best("thing", "panda", 10)}
        db.write_validation("thing", "panda", [
            Validated(ids[0], held, None, 0, '{"engine": "pybullet"}', ""),
            Validated(ids[1], held, None, 0, '{"engine": "pybullet"}', "")], rule)
        db.write_validation("thing", "panda", [  # a later MuJoCo run keeps PyBullet's rows
            Validated(ids[0], None, None, 0, "", "", mj_held, '{"engine": "mujoco"}'),
            Validated(ids[1], None, None, 0, "", "", dropped, '{"engine": "mujoco"}'),
            Validated(ids[2], None, None, 0, "", "", mj_held, '{"engine": "mujoco"}')], rule)
        back = {g.candidate: g for g in db.best("thing", "panda", 10)}
    assert (back[0].validation, back[0].mujoco) == (held, mj_held)
    assert (back[1].validation, back[1].mujoco) == (held, dropped)
    assert (back[2].validation, back[2].mujoco) == (None, mj_held)
    assert back[1].score == 0.0 and back[0].score > 0 and back[2].score > 0
    with sqlite3.connect(tmp_path / "g.db") as conn:
        assert conn.execute("SELECT COUNT(*), MIN(settings) FROM mujoco").fetchone() == (3, '{"engine": "mujoco"}')
        assert conn.execute("SELECT COUNT(*) FROM validation").fetchone() == (2,)


def test_ties_are_broken_by_epsilon_volume_seed_and_candidate_not_by_order(tmp_path: Path) -> None:
    with open_db(tmp_path / "g.db") as db:
        db.write_unit(unit(), None, [made_up(3, 0.0, fc=False), made_up(1, 0.0, fc=False)], RankingRule())
        assert [g.candidate for g in db.best("thing", "panda", 10)] == [1, 3]


def test_the_settled_epsilon_is_stored_and_adds_to_the_score_with_its_weight(tmp_path: Path) -> None:
    measures = Measures(3.0, 4.0, 0.01, 0.01, 1.0, ())
    grasps = [replace(made_up(0, 0.30), measures=replace(measures, settled_epsilon=0.0)),  # closing pushed it out
              replace(made_up(1, 0.05), measures=replace(measures, settled_epsilon=0.20)),
              replace(made_up(2, 0.10), measures=measures)]  # not measured: adds nothing
    with open_db(tmp_path / "g.db") as db:
        db.write_unit(unit(), None, grasps, RankingRule(eps_weight=1.0, settled_weight=2.0))
        back = {g.candidate: g for g in db.best("thing", "panda", 10)}
    assert [back[i].measures.settled_epsilon for i in range(3)] == [0.0, 0.20, None]  # type: ignore[union-attr]
    assert [g.candidate for g in sorted(back.values(), key=lambda g: g.rank)] == [1, 0, 2]  # 1: settled the best
    press_hold = (1.0 + 3.0 / 5.0) / 2.0  # push 1, resist 3 g of a 5 g cap
    assert_close([back[i].score for i in range(3)], [press_hold + 0.30, press_hold + 0.05 + 0.40, press_hold + 0.10])


def test_a_read_sqlite_refuses_is_a_database_error_of_one_line(box_db: Path, tmp_path: Path) -> None:
    broken = damaged(box_db, tmp_path / "broken.db")
    with open_db(broken, create=False, readonly=True) as db:
        assert db.object_row("box") is not None  # the objects table is whole
        for read in (db.pairs, lambda: db.best("box", "panda", 1), lambda: list(db.grasp_batches("box", "panda")),
                     db.validated):
            with pytest.raises(DatabaseError, match=r"broken\.db: cannot read the database \(.*malformed.*\); "
                                                    "check it with `grasp db check") as caught:
                read()
            assert isinstance(caught.value.__cause__, sqlite3.DatabaseError)
            assert len(str(caught.value).splitlines()) == 1


def test_a_settled_grasp_that_is_not_force_closure_ranks_below_every_closure_one(tmp_path: Path) -> None:
    measures = Measures(3.0, 4.0, 0.01, 0.01, 1.0, ())
    grasps = [replace(made_up(0, 0.0, fc=False), measures=replace(measures, settled_epsilon=0.40)),  # epsilon 0
              replace(made_up(1, 0.01), measures=replace(measures, settled_epsilon=0.0)),
              replace(made_up(2, 0.02), measures=replace(measures, settled_epsilon=0.0))]
    with open_db(tmp_path / "g.db") as db:
        db.write_unit(unit(), None, grasps, RankingRule())
        back = db.best("thing", "panda", 10)
    assert back[-1].candidate == 0 and back[-1].score > back[0].score  # the top score, ranked last
    assert [g.candidate for g in back] == [2, 1, 0]


def test_a_stored_model_gives_p_hold_to_records_and_ranks_by_it(tmp_path: Path) -> None:
    from planner.calibration.model import LogisticModel

    # p_hold falls with epsilon: the opposite of the formula's order
    model = LogisticModel("panda", ("epsilon",), np.zeros(1), np.full(1, 0.01), np.array([-1.0]), 0.0, 0.0, "test")
    grasps = [made_up(0, 0.01), made_up(1, 0.03), made_up(2, 0.02), made_up(3, 0.05, fc=False)]
    with open_db(tmp_path / "g.db") as db:
        db.write_unit(unit(), None, grasps, RankingRule())
        assert [g.candidate for g in db.best("thing", "panda", 10)][:3] == [1, 2, 0]  # the formula: by epsilon
        db.write_model(model, json.dumps({"labels": ["x.h5"]}), RankingRule())
        back = db.best("thing", "panda", 10)
        assert "x.h5" in db.model_source("panda") and db.model("panda").to_json() == model.to_json()  # type: ignore[union-attr]
    assert [g.candidate for g in back] == [0, 2, 1, 3]  # by p_hold; the non-closure grasp last
    expected = 1 / (1 + np.exp(np.array([0.01, 0.02, 0.03]) / 0.01))
    assert_close([g.p_hold for g in back[:3]], expected)
    assert_close([g.score for g in back[:3]], expected)  # reachability and trials not computed: neutral
    with sqlite3.connect(tmp_path / "g.db") as conn:  # stored in its column, written with the score
        stored = dict(conn.execute("SELECT candidate, p_hold FROM grasps").fetchall())
    assert_close([stored[i] for i in (0, 2, 1)], expected)
    new = made_up(4, 0.015)
    with open_db(tmp_path / "g.db") as db:  # a unit written after: scored by the stored model too
        db.write_unit(replace(unit(), chunk=1), None, [new], RankingRule())
        assert db.best("thing", "panda", 1)[0].candidate == 0
        assert [g.candidate for g in db.best("thing", "panda", 10)][:2] == [0, 4]
        assert_close([g.p_hold for g in db.best("thing", "panda", 2)][1], 1 / (1 + np.exp(1.5)))


def test_a_grasp_force_closure_after_the_squeeze_ranks_among_the_force_closure_ones(tmp_path: Path) -> None:
    """The database ranks as :func:`planner.db.ranking.rank_order` does: force closure as planned or squeezed
    first, whatever the scores; a squeeze not measured counts as not force closure."""
    measures = Measures(3.0, 4.0, 0.01, 0.01, 1.0, ())
    grasps = [replace(made_up(0, 0.0, fc=False), measures=replace(measures, settled_epsilon=0.4,
                                                                  squeezed_force_closure=False)),  # the top score
              replace(made_up(1, 0.0, fc=False), measures=replace(measures, squeezed_force_closure=True)),
              replace(made_up(2, 0.0, fc=False), measures=replace(measures, settled_epsilon=0.2)),  # not measured
              replace(made_up(3, 0.01), measures=replace(measures, squeezed_force_closure=True))]
    with open_db(tmp_path / "g.db") as db:
        db.write_unit(unit(), None, grasps, RankingRule())
        back = db.best("thing", "panda", 10)
        assert [g.candidate for g in back] == [3, 1, 0, 2]
        assert [g.candidate for g in db.scored(grasps, "panda")] == [3, 1, 0, 2]


def test_a_reader_leaves_no_wal_or_shm_files_and_writes_nothing(tmp_path: Path) -> None:
    path = tmp_path / "g.db"
    with open_db(path) as db:
        db.write_unit(unit(), None, [made_up(0, 0.05)], RankingRule())
    beside = [tmp_path / "g.db-wal", tmp_path / "g.db-shm"]
    assert not any(p.exists() for p in beside)  # the writer's clean close removed them
    with open_db(path, create=False, readonly=True) as db:
        assert [g.candidate for g in db.best("thing", "panda", 10)] == [0]
        with pytest.raises(sqlite3.OperationalError, match="readonly|query_only|read-only"):
            db._conn.execute("DELETE FROM grasps")
    assert not any(p.exists() for p in beside)  # `grasp best` left both until 2026-12-07
    assert [r[2] for r in rows(path)] == [0]


def test_a_reader_leaves_a_file_made_read_only_as_it_is_with_its_write_ahead_log(tmp_path: Path) -> None:
    """A reader opens a writable file read-write (its close removes the -wal/-shm, checkpointing a log a killed
    writer left); as root, access() said a file chmod 444 was writable too, and the reader wrote into it."""
    import os
    import shutil

    path = tmp_path / "g.db"
    with open_db(path) as db:
        db.write_unit(unit(), None, [made_up(0, 0.05)], RankingRule())
    writer = sqlite3.connect(path, isolation_level=None)  # a writer killed with its last commit in the log:
    writer.execute("PRAGMA wal_autocheckpoint = 0")
    writer.execute("INSERT INTO meta (key, value) VALUES ('note', 'in the log')")
    kept = tmp_path / "kept.db"  # its files as the kill left them
    for suffix in ("", "-wal"):
        shutil.copy(f"{path}{suffix}", f"{kept}{suffix}")
    writer.close()
    kept.chmod(0o444)
    before = (kept.read_bytes(), os.stat(kept).st_mtime_ns)
    with open_db(kept, create=False, readonly=True) as db:
        assert db.meta("note") == "in the log"
    assert (kept.read_bytes(), os.stat(kept).st_mtime_ns) == before
    assert Path(f"{kept}-wal").stat().st_size > 0  # the log stays for a writer to take in


def test_a_grasp_whose_squeezes_end_is_stored_ranks_after_every_force_closure_grasp(tmp_path: Path) -> None:
    """A grasp force closure only once squeezed whose squeeze's end is stored beside it (the same unit and
    candidate) ranks after every grasp that ranks first, its end standing for it, even where it scores above
    them; it stays stored as it was. One without a stored end (an import's: another unit, the same candidate
    number) still ranks with the force-closure grasps (issue 26)."""
    squeezed = Measures(3.0, 4.0, 0.01, 0.01, 1.0, (), settled_epsilon=0.4, squeezed_force_closure=True)
    parent = replace(made_up(0, 0.0, fc=False), measures=squeezed)  # the top score
    end = replace(made_up(0, 0.02), squeezed_from_turn=0.3, measures=replace(squeezed, squeezed_force_closure=False,
                                                                             settled_epsilon=0.0))
    other = replace(made_up(1, 0.01), measures=replace(squeezed, settled_epsilon=0.0))  # force closure, lowest
    neither = replace(made_up(2, 0.0, fc=False), measures=replace(squeezed, squeezed_force_closure=False))
    with open_db(tmp_path / "g.db") as db:
        db.write_unit(unit(), None, [parent, end, other, neither], RankingRule())
        back = db.best("thing", "panda", 10)
        assert [(g.candidate, g.squeezed_from_turn is not None) for g in back] == [(0, True), (1, False),
                                                                                     (0, False), (2, False)]
        assert back[2].score > back[0].score and back[2].measures == squeezed  # as stored, measures and all
        db.write_unit(unit(chunk=1), None, [parent], RankingRule())  # the import's: no end beside it
        back = db.best("thing", "panda", 10)
        assert [(g.unit_id, g.candidate, g.squeezed_from_turn is not None) for g in back][:2] == [
            (back[0].unit_id, 0, False), (back[1].unit_id, 0, True)] and back[0].unit_id != back[1].unit_id
        assert [g.end_kept for g in back] == [False, False, False, True, False]


def test_a_database_ranked_the_earlier_way_is_ranked_again_at_the_next_write(tmp_path: Path) -> None:
    """A database whose grasps were ranked before a stored squeeze's end stood for its parent (its ``meta.ranking``
    holds the earlier formula): the next ``generate`` or ``import`` (:meth:`Database.apply_rule`) re-ranks it."""
    squeezed = Measures(3.0, 4.0, 0.01, 0.01, 1.0, (), settled_epsilon=0.4, squeezed_force_closure=True)
    parent = replace(made_up(0, 0.0, fc=False), measures=squeezed)
    end = replace(made_up(0, 0.02), squeezed_from_turn=0.3, measures=replace(squeezed, squeezed_force_closure=False))
    path = tmp_path / "g.db"
    with open_db(path) as db:  # as `grasp generate` writes: the rule, then the unit
        db.apply_rule(RankingRule())
        db.write_unit(unit(), None, [parent, end, made_up(1, 0.01)], RankingRule())
    with sqlite3.connect(path) as conn:  # as the earlier version left it: its formula, the parent first
        stored = json.loads(conn.execute("SELECT value FROM meta WHERE key = 'ranking'").fetchone()[0])
        stored["formula"] = stored["formula"].replace(" (but for one whose squeeze's end is stored as a grasp of its "
                                                      "own, which stands for it)", "")
        conn.execute("UPDATE meta SET value = ? WHERE key = 'ranking'", (json.dumps(stored, sort_keys=True),))
        conn.execute("UPDATE grasps SET rank = 1 + candidate + (squeezed_from_turn IS NOT NULL) + (candidate = 1)")
    with open_db(path) as db:
        assert [g.force_closure for g in db.best("thing", "panda", 10)] == [False, True, True]
        assert db.apply_rule(RankingRule())
        assert [(g.candidate, g.force_closure) for g in db.best("thing", "panda", 10)][2] == (0, False)


def test_a_stored_p_hold_is_the_one_its_stored_grasp_gives(tmp_path: Path, shipped_models: None) -> None:
    """p_hold was computed from the record before its pose and contacts were rounded as stored: up to 1e-5 off
    what the stored grasp gives (the mug's 1,952: every one), so an import of its own ACRONYM export, or a
    re-score, changed p_hold and swapped ranks. Stored as the stored grasp gives it, to the last bits."""
    from helpers import FAST, grasp

    from planner.calibration import features

    db_path = tmp_path / "g.db"
    code, _, err = grasp("generate", "box", "--hand", "panda", "--db", str(db_path), "--quiet", *FAST)
    assert code == 0, err
    with open_db(db_path, create=False, readonly=True) as db:
        grasps = db.best("box", "panda", 100_000)
        model = db.model("panda")
    assert model is not None and len(grasps) >= 3
    again = model.predict(features.of_grasps(grasps))
    ulps = 1e-12  # a batch of other rows (the unit's, in its order) moves a BLAS product's last bits
    np.testing.assert_allclose(again, [g.p_hold for g in grasps], rtol=0, atol=ulps)
