"""MoveIt YAML: a file written in several batches loads as one list."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import pytest
import yaml

from planner import api
from planner.datasets import exporter, moveit


def test_a_pair_written_in_several_batches_loads_with_safe_load(db: Path, tmp_path: Path,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """Each batch was dumped on its own, anchors numbered from id001 each time: a pair of more than one batch
    (over 5,000 grasps) gave a file that yaml.safe_load refuses (duplicate anchor 'id001')."""
    total = sqlite3.connect(db).execute("SELECT COUNT(*) FROM grasps WHERE object = 'box'").fetchone()[0]
    monkeypatch.setattr(exporter, "BATCH_SIZE", 2)
    assert total > 2 * exporter.BATCH_SIZE
    api.export(db, "moveit", tmp_path, objects=["box"])
    text = (tmp_path / moveit.relative_path("box", "panda")).read_text()
    messages = yaml.safe_load(text)
    assert [m["id"] for m in messages] == [f"box/panda/{rank}" for rank in range(1, total + 1)]
    assert "&id" not in text and "*id" not in text  # every value written in full: no anchors, no aliases
    assert all(m["grasp_posture"]["joint_names"] == m["pre_grasp_posture"]["joint_names"] for m in messages)


def test_no_vector_is_written_with_a_negative_zero(db: Path, tmp_path: Path) -> None:
    """The retreat, -approach of the Panda's (0, 0, 1), was written {x: -0.0, y: -0.0, z: -1.0}."""
    api.export(db, "moveit", tmp_path, objects=["box"], top=3)
    text = (tmp_path / moveit.relative_path("box", "panda")).read_text()
    messages = yaml.safe_load(text)
    retreat = messages[0]["post_grasp_retreat"]["direction"]["vector"]
    assert retreat == {"x": 0.0, "y": 0.0, "z": -1.0}
    assert "-0.0," not in text and "-0.0}" not in text


def test_libyaml_writes_the_text_the_pure_python_dumper_writes(db: Path, tmp_path: Path,
                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    """The MoveIt export dumped with PyYAML's pure-Python emitter, 189 grasps a second (44.6 s of a six-object
    export whose other formats took 2-3 s): libyaml's, where PyYAML has it, writes the same bytes."""
    if not yaml.__with_libyaml__:
        pytest.skip("PyYAML built without libyaml")
    assert issubclass(moveit._dumper(), yaml.CSafeDumper)
    api.export(db, "moveit", tmp_path / "c", objects=["box"])
    pure = moveit._dumper(pure=True)
    monkeypatch.setattr(moveit, "_dumper", lambda: pure)
    api.export(db, "moveit", tmp_path / "p", objects=["box"])
    path = moveit.relative_path("box", "panda")
    text = (tmp_path / "c" / path).read_bytes()
    assert text == (tmp_path / "p" / path).read_bytes() and len(yaml.safe_load(text)) > 1
