"""A validation worker builds each stored object once, not once a task."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from planner.db.store import open_db
from planner.validation import kept_objects, run
from planner.validation.mujoco_settings import MujocoSettings


@pytest.fixture
def counted(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """The names of the objects built, in order (nothing kept before)."""
    built: list[str] = []
    stored_object = kept_objects.stored_object

    def counting(row):  # type: ignore[no-untyped-def]
        built.append(row.name)
        return stored_object(row)

    monkeypatch.setattr(kept_objects, "stored_object", counting)
    kept_objects.forget()
    yield built
    kept_objects.forget()


def test_the_tasks_of_one_object_build_it_once(box_db: Path, counted: list[str]) -> None:
    with open_db(box_db, create=False, readonly=True) as db:
        row = db.object_row("box")
        grasps = [g for batch in db.grasp_batches("box", "panda") for g in batch][:4]
    assert row is not None and len(grasps) == 4
    tasks = [run.Task(row, "panda", tuple(grasps[i:i + 2]), 0, MujocoSettings(), None) for i in (0, 2)]
    first, second = (run.run_task(t) for t in tasks)
    assert first.error is None and second.error is None and len(first.trials) == len(second.trials) == 2
    assert counted == ["box"]
    alone = run.run_task(tasks[1])  # the same results from the kept object as from a new one
    kept_objects.forget()
    again = run.run_task(tasks[1])
    assert counted == ["box", "box"] and alone.trials == second.trials == again.trials


def test_another_row_is_another_object() -> None:
    from planner.geometry.solid import load_object

    obj = load_object("box")
    row = run_row(obj)
    assert kept_objects.row_key(row) == kept_objects.row_key(replace(row, com=row.com.copy()))
    assert kept_objects.row_key(row) != kept_objects.row_key(replace(row, com=row.com + [0.0, 0.0, 1e-9]))
    assert kept_objects.row_key(row) != kept_objects.row_key(replace(row, mass=row.mass * 2))


def run_row(obj):  # type: ignore[no-untyped-def]
    from planner.db.rows import ObjectRow

    return ObjectRow(obj.name, obj.source_file, obj.file_scale, obj.mass, obj.friction, obj.density, obj.volume,
                     np.asarray(obj.com, float), np.asarray(obj.inertia, float), obj.mesh_hash)


def test_a_run_in_this_process_forgets_its_objects(box_db: Path, tmp_path: Path, counted: list[str]) -> None:
    import shutil

    db = tmp_path / "g.db"
    shutil.copy(box_db, db)
    for seed in (0, 1):  # the second run (another seed: not skipped) builds the object again, as a file edited
        run.validate(db, every=True, robust_samples=0, workers=1, objects=["box"], seed=seed)  # since would be
        assert not kept_objects._OBJECTS
    assert counted == ["box", "box"]
