"""What ``grasp best`` says when it finds nothing: the project's error line
and a command or option that helps."""

from __future__ import annotations

import shlex
from pathlib import Path

import trimesh
from helpers import FAST, grasp, one_line_error

from planner.specs.objects import resolve_spec


def test_best_of_a_stored_mesh_suggests_its_file(tmp_path: Path) -> None:
    mesh = tmp_path / "cone.obj"
    trimesh.creation.cone(radius=0.03, height=0.08, sections=24).export(mesh)
    db = tmp_path / "g.db"
    code, _, err = grasp("generate", str(mesh), "--hand", "panda", "--db", str(db), "--quiet", "--friction", "0.8",
                         *FAST)
    assert code == 0, err
    code, _, err = grasp("best", "cone", "--hand", "pr2", "--db", str(db))
    one_line_error(code, err, 2, "no grasps of 'cone' for hand 'pr2'")
    command = shlex.split(err.split("`")[1])
    assert command[:2] == ["grasp", "generate"] and command[command.index("--hand") + 1] == "pr2"
    assert Path(command[2]) == mesh and resolve_spec(command[2]).name == "cone"  # a real object, not the bare name
    assert command[command.index("--friction") + 1] == "0.8" and command[command.index("--db") + 1] == str(db)
    code, _, err = grasp(*command[1:], "--quiet", *FAST)  # the suggestion runs, at the stored values
    assert code == 0, err


def test_best_at_a_pose_out_of_reach_is_an_error_with_a_hint(box_db: Path) -> None:
    code, out, err = grasp("best", "box", "--hand", "panda", "--db", str(box_db), "--object-pose",
                           "5,0,0.04,0,0,0,1", "--max-candidates", "3")
    one_line_error(code, err, 1, "grasp: error: none of the 3 best grasps of 'box'", "--max-candidates 30")
    assert out == ""


def test_best_of_an_object_swept_to_nothing_says_why(tmp_path: Path) -> None:
    mesh = tmp_path / "bigcube.obj"
    trimesh.creation.box(extents=[0.3, 0.3, 0.3]).export(mesh)  # wider than the Panda opens
    db = tmp_path / "g.db"
    code, _, err = grasp("generate", str(mesh), "--hand", "panda", "--db", str(db), "--quiet", *FAST)
    assert code == 0, err
    code, _, err = grasp("best", "bigcube", "--hand", "panda", "--db", str(db))
    one_line_error(code, err, 2, "no grasps of 'bigcube' for hand 'panda'", "kept none (rejected: too_wide",
                   "too_wide: the object is wider than the hand opens")
    assert err.index("try another hand") < err.index("if its sweep was cut short")  # not a plain "run it"
    # show said 'no grasp of rank 1', export 'no grasp of the 0 (object, hand) pairs selected passes the filters
    # (--top, --min-epsilon, --label)' when none was given
    code, _, err = grasp("show", "bigcube", "--hand", "panda", "--db", str(db), "--out", str(tmp_path / "x.png"))
    one_line_error(code, err, 2, "no grasps of 'bigcube' for hand 'panda'", "kept none (rejected: too_wide")
    code, _, err = grasp("export", "--db", str(db), "--format", "csv", "--out", str(tmp_path / "csv"))
    one_line_error(code, err, 2, "no grasps stored: nothing written; `grasp best OBJECT --hand HAND --db")
    assert not (tmp_path / "csv").exists()
