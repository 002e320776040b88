"""The Python API: building, failures recorded, queries (resuming after a
kill: tests/test_reliability.py)."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import numpy as np
import pytest

from planner import api
from planner.db.store import open_db
from planner.errors import DatabaseError, InputError
from planner.plan.sweep import SweepSettings

#: The Panda's own sampler (antipodal), resolved so that its number of chunks is known.
SMALL = SweepSettings(approaches=8, rolls=2, preshapes=("wide",), chunk=4, reach_placements=1).resolved("antipodal")


def test_failing_object_is_recorded_and_the_batch_goes_on(tmp_path: Path) -> None:
    bad = tmp_path / "bad.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nv 0 nan 0\nf 1 2 3\n")
    db = tmp_path / "b.db"
    summary = api.generate([str(bad), "box"], "panda", db_path=db, settings=SMALL, seed=11, workers=2)
    assert "bad" in summary.failed and "NaN" in summary.failed["bad"]
    with sqlite3.connect(db) as conn:
        status = dict(conn.execute("SELECT object, status FROM units WHERE chunk = 0").fetchall())
        errors = conn.execute("SELECT error FROM units WHERE object = 'bad'").fetchall()
    assert status == {"bad": "failed", "box": "done"}
    assert all("NaN" in e[0] for e in errors)
    # a rerun retries only the failed units
    again = api.generate([str(bad), "box"], "panda", db_path=db, settings=SMALL, seed=11, workers=1)
    assert again.skipped == SMALL.chunks() and again.units == SMALL.chunks()


def test_best_on_missing_db_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(DatabaseError, match="no such database"):
        api.best("box", "panda", db_path=tmp_path / "none.db")


def test_best_and_plan_check_inputs_before_any_work(box_db: Path) -> None:
    assert [g.rank for g in api.best("box", "panda", db_path=box_db, top=2)] == [1, 2]
    with pytest.raises(InputError, match="--top must be at least 1"):
        api.best("box", "panda", db_path=box_db, top=0)
    with pytest.raises(InputError, match="no grasps of 'sphere' for hand 'panda'.*objects with grasps for panda: box"):
        api.best("sphere", "panda", db_path=box_db)
    with pytest.raises(InputError, match="no objects given"):
        api.plan_units([], "panda", SweepSettings(), 0)
    units = api.plan_units(["box", "box", "sphere"], "panda", SMALL, 3)
    assert [(u.label, u.chunk) for u in units] == [(o, c) for o in ("box", "sphere") for c in range(SMALL.chunks())]


def test_descriptions_list_hands_with_their_preshapes_and_objects() -> None:
    hands = {spec.name: [s.name for s in shapes] for spec, shapes in api.hands()}
    assert hands["panda"] == ["wide", "half"]
    assert {"mug", "box"} <= set(api.objects())


def test_show_and_best_at_use_the_stored_mesh(stored_db: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The duck was generated at --scale 1.5: the registry's duck is not the one its grasps hold."""
    from planner.geometry.solid import load_object
    from planner.present import render

    shown: list = []
    blank = render.View(np.zeros((4, 4, 3)), np.zeros((0, 2)))
    monkeypatch.setattr(render, "grasp_views", lambda hand, obj, g: shown.append(obj) or [blank])
    api.show("duck", "panda", tmp_path / "d.png", db_path=stored_db)
    assert np.array_equal(shown[0].mesh.vertices, load_object("duck", scale=1.5).mesh.vertices)
    with open_db(stored_db, create=False, readonly=True) as db:
        assert api.resolve_object(db, "duck")[1].scale == pytest.approx(1.5 * load_object("duck").file_scale)
        assert api.resolve_object(db, "random_007") == ("random_007", None)  # known, not stored
    with pytest.raises(InputError, match="no grasps of 'random_007' for hand 'panda'"):
        api.best_at("random_007", "panda", [0.5, 0, 0, 0, 0, 0, 1], db_path=stored_db)


@pytest.mark.parametrize("distance", [-0.1, float("nan"), float("inf")])
def test_a_pregrasp_distance_that_is_no_distance_is_an_input_error(box_db: Path, distance: float) -> None:
    """best_at took a negative or nan back-off (the pre-grasp then in front of the grasp, or nowhere)."""
    with pytest.raises(InputError, match="pregrasp_distance must be a finite distance"):
        api.best_at("box", "panda", [0.5, 0, 0.04, 0, 0, 0, 1], db_path=box_db, pregrasp_distance=distance)


@pytest.mark.parametrize("pose", [np.eye(4), "abc", [0.5, 0, 0.04, 0, 0, 0, "w"]])
def test_a_pose_of_the_wrong_kind_is_an_input_error(box_db: Path, pose: object) -> None:
    with pytest.raises(InputError, match="needs 7 finite numbers"):
        api.best_at("box", "panda", pose, db_path=box_db)  # type: ignore[arg-type]
