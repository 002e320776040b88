"""Items a new user met (session of stop 65): what `grasp best --on-table` prints to repeat a pose, what `grasp view`
says when its port is taken."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from helpers import grasp

from planner.api.on_table import TableGrasps
from planner.geometry.stable import RestingPose


def test_an_on_table_pose_to_repeat_has_no_negative_zero() -> None:
    """`grasp best mug --on-table` printed `--object-pose 0.49...,-0.0024,0.0,-0.0,0.0,-0.0,1.0`: a sign on a zero
    the user retypes."""
    pose = np.eye(4)
    pose[:3, 3] = [0.5, -0.0, 0.02]
    pose[:3, :3] = np.diag([1.0, -1.0, -1.0]) @ np.diag([1.0, -1.0, -1.0])  # the identity with signed zeros off it
    pose[0, 1] = pose[1, 0] = -0.0
    t = TableGrasps(RestingPose(pose.copy(), 0.5), pose, [], [])
    seven = t.object_pose7()
    assert ",".join(repr(v) for v in seven) == "0.5,0.0,0.02,0.0,0.0,0.0,1.0"


def test_view_says_when_its_port_is_taken(box_db: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`grasp view box --port 8080` with 8080 taken served on 8081 and said only the new address: a user with the
    old one bookmarked saw another program."""
    import socket

    from planner.cli import view

    def interrupted(seconds: float) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(view.time, "sleep", interrupted)
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        code, out, err = grasp("view", "box", "--hand", "panda", "--db", str(box_db), "--top", "2", "--port",
                               str(port))
    assert code == 130
    assert f"port {port} is in use: serving on port" in err
    assert "grasp viewer: http://127.0.0.1:" in out and f":{port} " not in out


def test_a_pictures_caption_says_force_closure_as_best_does(box_db: Path) -> None:
    """`grasp show mug --rank 9`: "score 0.9974, epsilon 0.0000, reach n/a": a grasp force closure only once
    squeezed looked like a zero-quality grasp scored near 1, with no p_hold, and "n/a" where `best` says "not
    computed" (which the score counts as 1)."""
    from dataclasses import replace

    from planner import api
    from planner.present.render import title

    top = api.best("box", "panda", db_path=box_db, top=1)[0]
    squeezed = replace(top.measures, squeezed_force_closure=True, squeezed_epsilon=0.0123, squeeze_turn=0.35)
    text = title(replace(top, force_closure=False, epsilon=0.0, measures=squeezed, reachability=None, p_hold=0.9974))
    assert "p_hold 0.997, score" in text
    assert "epsilon 0.0000 (NOT force closure as planned, force closure once squeezed, turned 20.1 deg)" in text
    assert "reach not computed" in text
    plain = title(replace(top, force_closure=False, epsilon=0.0, measures=replace(top.measures,
                                                                                 squeezed_force_closure=False)))
    assert "epsilon 0.0000 (NOT force closure)" in plain
    assert f"epsilon {top.epsilon:.4f} (force closure)" in title(top)


def test_validate_and_report_of_a_database_whose_sweeps_kept_nothing_say_so(box_db: Path, tmp_path: Path) -> None:
    """`grasp generate cyl.stl --scale 10` kept no grasp (too wide); `grasp validate` then said "run `grasp
    generate ... --db z.db` first" and `grasp report` "no grasps; run `grasp generate ...`": the user had."""
    import shutil
    import sqlite3

    from helpers import one_line_error

    db = tmp_path / "z.db"
    shutil.copy(box_db, db)
    with sqlite3.connect(db) as conn:
        conn.execute("DELETE FROM grasps")
    kept_none = f"no grasps in {db}: the sweeps of its objects (box) kept none; `grasp best box --hand HAND --db {db}`"
    for command in (["validate", "--db", str(db)], ["report", "--db", str(db), "--out", str(tmp_path / "r.html")]):
        code, _, err = grasp(*command)
        one_line_error(code, err, 2, kept_none)
        assert "grasp generate" not in err
