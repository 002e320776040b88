"""``grasp validate`` and ``grasp report`` on the command line."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from helpers import FAST, grasp


def test_validate_json_summary_and_failures(validated_db: Path, tmp_path: Path) -> None:
    copy = tmp_path / "v.db"
    shutil.copy(validated_db, copy)
    code, out, err = grasp("validate", "--db", str(copy), "--object", "box", "--top", "1", "--robust", "0",
                           "--workers", "1", "--json")
    assert code == 0, err
    summary = json.loads(out)
    assert summary["grasps"] == 1 and summary["successes"] in (0, 1) and summary["failed"] == {}


def test_validate_in_mujoco_stores_its_verdicts_apart(validated_db: Path, tmp_path: Path) -> None:
    import sqlite3

    copy = tmp_path / "v.db"
    shutil.copy(validated_db, copy)
    with sqlite3.connect(copy) as conn:
        before = conn.execute("SELECT * FROM validation ORDER BY grasp_id").fetchall()
    code, out, err = grasp("validate", "--db", str(copy), "--object", "box", "--top", "2", "--robust", "0",
                           "--workers", "1", "--engine", "mujoco", "--json")
    assert code == 0, err
    assert json.loads(out)["grasps"] == 2
    with sqlite3.connect(copy) as conn:
        assert conn.execute("SELECT * FROM validation ORDER BY grasp_id").fetchall() == before
        rows = conn.execute("SELECT reason, settings FROM mujoco").fetchall()
    assert len(rows) == 2 and all(json.loads(settings)["engine"] == "mujoco" for _, settings in rows)
    assert all(reason in ("held", "slipped", "squeezed_out", "no_contact", "start_overlap") for reason, _ in rows)
    code, out, err = grasp("best", "box", "--hand", "panda", "--db", str(copy), "--top", "1000", "--json")
    assert code == 0, err
    tried = [g for g in json.loads(out) if g["mujoco_reason"] is not None]
    assert len(tried) == 2 and {g["mujoco_reason"] for g in tried} == {reason for reason, _ in rows}


def test_an_unknown_engine_is_one_line(validated_db: Path) -> None:
    code, _, err = grasp("validate", "--db", str(validated_db), "--engine", "havok")
    assert code == 2 and "havok" in err and "Traceback" not in err


def test_report_prints_the_file_it_wrote(validated_db: Path, tmp_path: Path) -> None:
    code, out, err = grasp("report", "--db", str(validated_db), "--out", str(tmp_path / "r.html"))
    assert code == 0 and out.splitlines()[0] == str(tmp_path / "r.html"), err
    assert all(line.startswith("coverage ") for line in out.splitlines()[1:])


def test_validate_all_force_closure_tests_exactly_the_grasps_that_rank_first(tmp_path: Path) -> None:
    """--force-closure: the grasps force closure as planned or once squeezed (planner.db.ranking.FIRST), but not
    one whose squeeze's end is stored beside it (the end is tried for it)."""
    import sqlite3

    from planner.db.ranking import FIRST_SQL, first_sql

    copy = tmp_path / "v.db"
    code, _, err = grasp("generate", "box", "--hand", "panda", "--db", str(copy), "--sampler", "surface", "--quiet",
                         *FAST)
    assert code == 0, err
    with sqlite3.connect(copy) as conn:  # two not force closure as planned, force closure once squeezed
        squeezed = [i for (i,) in conn.execute("SELECT id FROM grasps WHERE force_closure = 0 ORDER BY id LIMIT 2")]
        conn.execute(f"UPDATE grasps SET squeezed_force_closure = 1 WHERE id IN {tuple(squeezed)}")
        columns = [c for (_, c, *_) in conn.execute("PRAGMA table_info(grasps)") if c != "id"]
        copied = ", ".join("p.candidate" if c == "candidate" else "0.3" if c == "squeezed_from_turn" else f"e.{c}"
                           for c in columns)  # the second's squeeze's end, stored: a force-closure grasp's copy
        conn.execute(f"INSERT INTO grasps ({', '.join(columns)}) SELECT {copied} FROM grasps e, grasps p WHERE "
                     "e.id = (SELECT MIN(id) FROM grasps WHERE force_closure = 1) AND p.id = ?", (squeezed[1],))
        total, closure, planned = conn.execute(f"SELECT COUNT(*), SUM({FIRST_SQL}), SUM(force_closure) "
                                               "FROM grasps").fetchone()
    assert 0 < planned < closure < total, "the box database should hold grasps of the three kinds"
    assert closure == planned + 1, "one force closure once squeezed ranks first, the other's end stands for it"
    code, out, err = grasp("validate", "--db", str(copy), "--all", "--force-closure", "--robust", "0",
                           "--workers", "1", "--json")  # the default engine: MuJoCo's trial
    assert code == 0, err
    assert json.loads(out)["grasps"] == closure
    with sqlite3.connect(copy) as conn:
        tested = conn.execute(f"SELECT {first_sql('g')}, g.id FROM mujoco v JOIN grasps g ON g.id = v.grasp_id"
                              ).fetchall()
        assert conn.execute("SELECT COUNT(*) FROM validation").fetchone() == (0,)
    assert len(tested) == closure and all(fc == 1 for (fc, _) in tested)
    assert squeezed[0] in {i for _, i in tested} and squeezed[1] not in {i for _, i in tested}


@pytest.mark.parametrize("engine", ["mujoco", "pybullet"])
def test_validate_shakes_an_imported_object_with_its_stored_mass_and_friction(tmp_path: Path, monkeypatch,  # type: ignore[no-untyped-def]
                                                                              engine: str) -> None:
    """An ACRONYM file of a user mesh with mass 0.05 kg and friction 1.0 (not
    the 0.2 kg / 0.5 a mesh gets by default): each engine's trial gets those."""
    import sqlite3

    import h5py
    import numpy as np
    import trimesh

    from planner.specs.hands import load_hand
    from planner.validation import run

    (tmp_path / "meshes").mkdir()
    trimesh.creation.box(extents=(0.04, 0.04, 0.04)).export(tmp_path / "meshes" / "crate.obj")
    panda = load_hand("panda")
    pose = np.eye(4)
    pose[:3, 3] = -panda.tcp  # the tool centre point at the crate's centre, approaching along +z
    path = tmp_path / "crate.h5"
    with h5py.File(path, "w") as f:
        f["gripper/type"] = "franka_panda"
        f["object/file"], f["object/scale"] = "meshes/crate.obj", 1.0
        f["object/mass"], f["object/friction"] = 0.05, 1.0
        f["grasps/transforms"] = (pose @ panda.export_frame)[None]
        f["grasps/qualities/flex/object_in_gripper"] = np.ones(1, np.int64)
    db = tmp_path / "g.db"
    code, _, err = grasp("import", str(path), "--db", str(db))
    assert code == 0, err
    with sqlite3.connect(db) as conn:
        assert conn.execute("SELECT mass, friction FROM objects WHERE name = 'crate'").fetchall() == [(0.05, 1.0)]
        assert conn.execute("SELECT COUNT(*) FROM grasps").fetchone()[0] == 1
    shaken = []

    def trials(hand, obj, grasps, settings):  # type: ignore[no-untyped-def]
        shaken.append((obj.name, obj.mass, obj.friction))
        return real(hand, obj, grasps, settings)

    from planner.validation import mujoco_trial

    module = mujoco_trial if engine == "mujoco" else run
    real = module.trials
    monkeypatch.setattr(module, "trials", trials)
    code, out, err = grasp("validate", "--db", str(db), "--all", "--robust", "0", "--workers", "1", "--json",
                           "--engine", engine)
    assert code == 0, err
    assert json.loads(out)["grasps"] == 1 and shaken == [("crate", 0.05, 1.0)]


def test_a_run_with_nothing_new_to_try_says_so(validated_db: Path, tmp_path: Path) -> None:
    """It said "validated 0 grasps in pybullet: 0 held (0%); 3 already tried ...": 0% of nothing."""
    copy = tmp_path / "v.db"
    shutil.copy(validated_db, copy)
    code, out, err = grasp("validate", "--db", str(copy), "--object", "box", "--top", "3", "--robust", "2",
                           "--workers", "1", "--engine", "pybullet")
    assert code == 0, err
    assert out.startswith("nothing new to try in pybullet; 3 already tried with these settings and seed, kept ("), out
    assert "0%" not in out and "validated 0" not in out
    import sqlite3

    with sqlite3.connect(copy) as conn:
        conn.execute("UPDATE grasps SET force_closure = 0, squeezed_force_closure = MIN(squeezed_force_closure, 0) "
                     "WHERE object = 'sphere'")
    code, out, err = grasp("validate", "--db", str(copy), "--object", "sphere", "--force-closure", "--robust", "0",
                           "--workers", "1", "--engine", "pybullet")
    assert code == 0, err
    assert out == ("nothing new to try in pybullet: no stored grasp is selected (none is force closure as planned "
                   "or once squeezed)\n"), out


@pytest.mark.parametrize("outcome", ["failed", "diverged"])
def test_a_run_whose_trials_all_failed_or_diverged_does_not_say_nothing_was_selected(
        outcome: str, validated_db: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Every task failing read "nothing new to try in mujoco: no stored grasp is selected" (three were, and
    tried), and every trial diverging "validated 0 grasps in mujoco: 0 held (0%)": 0% of nothing."""
    from planner.record.grasp import Trial
    from planner.validation import run
    from planner.validation.mujoco_settings import DIVERGED

    def ends(task: run.Task) -> run.TaskResult:
        if outcome == "failed":
            return run.TaskResult(task, error="boom")
        return run.TaskResult(task, [Trial(False, 1, 0.0, 0.0, 0.0, 0.0, DIVERGED) for _ in task.grasps],
                              [None] * len(task.grasps))

    copy = tmp_path / "v.db"
    shutil.copy(validated_db, copy)
    monkeypatch.setattr(run, "run_task", ends)
    code, out, err = grasp("validate", "--db", str(copy), "--object", "box", "--top", "3", "--robust", "0",
                           "--workers", "1", "--engine", "mujoco")
    assert "no stored grasp is selected" not in out and "0%" not in out and "validated 0" not in out, out
    if outcome == "failed":
        assert code == 2 and out.startswith("no grasp given a verdict in mujoco: its trials failed"), out
        assert "grasp: error: box/panda: boom" in err
    else:
        assert code == 0 and out.startswith("no grasp given a verdict in mujoco; 3 diverged"), out


def test_the_help_says_which_grasps_force_closure_selects() -> None:
    """--force-closure and --top select what ranks first (planner.db.ranking.FIRST): the help says so."""
    code, out, err = grasp("validate", "--help")
    assert code == 0, err
    said = " ".join(out.split())
    assert ("Of the grasps that rank first only: force closure as planned, or once squeezed where that squeeze's "
            "end is not stored beside it (the end is tried for it)." in said)
    assert ("grasps force closure as planned, or once squeezed where that squeeze's end is not stored beside them, "
            "rank first" in said)
