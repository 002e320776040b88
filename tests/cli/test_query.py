"""``grasp best`` and ``grasp show``: the documented JSON, and fingers that really touch."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from helpers import grasp, one_line_error


def test_best_json_has_the_documented_keys(box_db: Path) -> None:
    code, out, err = grasp("best", "box", "--hand", "panda", "--db", str(box_db), "--top", "3", "--json")
    assert code == 0, err
    grasps = json.loads(out)
    assert 1 <= len(grasps) <= 3
    keys = {"object", "hand", "preshape", "pose", "joints", "epsilon", "volume", "force_closure", "contacts", "rank",
            "score", "resist_worst", "resist_mean", "open_margin", "close_margin", "push", "feasibility"}
    assert keys <= set(grasps[0])
    assert [g["rank"] for g in grasps] == list(range(1, len(grasps) + 1))
    pose = np.array(grasps[0]["pose"])
    assert pose.shape == (4, 4) and np.allclose(pose[:3, :3] @ pose[:3, :3].T, np.eye(3), atol=1e-6)
    assert grasps[0]["epsilon"] > 0 and grasps[0]["force_closure"]
    assert {"point", "normal", "link"} <= set(grasps[0]["contacts"][0])


def test_best_grasp_fingers_really_touch_the_object(box_db: Path) -> None:
    """Re-place the hand from the JSON alone and measure the true finger gaps."""
    from planner.geometry.solid import load_object
    from planner.sim import Sim
    from planner.specs.hands import load_hand

    code, out, err = grasp("best", "box", "--hand", "panda", "--db", str(box_db), "--json")
    assert code == 0, err
    top = json.loads(out)[0]
    hand, obj = load_hand("panda"), load_object("box")
    with Sim() as sim:
        body = sim.load_urdf(hand.urdf)
        target = sim.add_static_mesh(obj.mesh.vertices, obj.mesh.faces)
        sim.set_pose(body, np.array(top["pose"]))
        sim.set_joints(body, top["joints"])
        for finger in ("panda_leftfinger", "panda_rightfinger"):
            pairs = sim.closest(body.uid, target, 0.01, body.links[finger])
            gap = pairs.min_distance + hand.distance_offset
            assert -0.001 <= gap <= 0.001, (finger, gap)
    assert top["epsilon"] > 0


def test_best_prints_one_line_per_grasp_and_show_writes_a_png(box_db: Path, tmp_path: Path) -> None:
    code, out, err = grasp("best", "box", "--hand", "panda", "--db", str(box_db), "--top", "2")
    assert code == 0, err
    lines = out.strip().splitlines()
    assert len(lines) == 2 and lines[0].startswith("#1 box/panda preshape=wide p_hold=n/a score=")  # no model: n/a
    assert " holds=" in lines[0] and " push=" in lines[0] and " feasibility=" in lines[0]  # the analytic measures
    code, out, err = grasp("show", "box", "--hand", "panda", "--db", str(box_db), "--out", str(tmp_path / "g.png"))
    assert code == 0 and (tmp_path / "g.png").stat().st_size > 1000, err


def test_every_query_takes_the_database_name_of_a_stored_object(stored_db: Path, tmp_path: Path) -> None:
    """A user mesh in millimetres and a built-in generated at --scale 1.5,
    by the names the database stores them under; and an imported object."""
    for name in ("capsule", "duck"):
        code, _, err = grasp("show", name, "--hand", "panda", "--db", str(stored_db), "--out", str(tmp_path / "s.png"))
        assert code == 0, err
        code, out, err = grasp("best", name, "--hand", "panda", "--db", str(stored_db), "--json")
        assert code == 0 and json.loads(out)[0]["object"] == name, err
        code, out, err = grasp("best", name, "--hand", "panda", "--db", str(stored_db), "--object-pose",
                               "0.5,0,0.05,0,0,0,1", "--max-candidates", "5", "--json")
        assert code == 0 and isinstance(json.loads(out), list), err
    code, _, err = grasp("export", "--db", str(stored_db), "--format", "acronym", "--out", str(tmp_path / "h5"),
                         "--object", "capsule", "--quiet")
    assert code == 0, err
    imported = tmp_path / "imported.db"
    code, _, err = grasp("import", str(tmp_path / "h5" / "capsule__panda.h5"), "--db", str(imported))
    assert code == 0, err
    code, _, err = grasp("show", "capsule", "--hand", "panda", "--db", str(imported), "--out", str(tmp_path / "i.png"))
    assert code == 0 and (tmp_path / "i.png").stat().st_size > 1000, err


@pytest.mark.parametrize("command", [["show", "--out", "x.png"], ["best"], ["best", "--object-pose", "0,0,0,0,0,0,1"]])
def test_an_object_neither_stored_nor_known_is_a_one_line_error(stored_db: Path, command: list[str]) -> None:
    code, _, err = grasp(command[0], "teapot", "--hand", "panda", "--db", str(stored_db), *command[1:])
    one_line_error(code, err, 2, "unknown object 'teapot': not stored in", "(objects: box, capsule, duck)",
                   "not a built-in name, random_NNN or mesh file")


def test_the_barrett_settles_by_default_and_best_prints_its_settled_epsilon(tmp_path: Path) -> None:
    small = ["--approaches", "2", "--rolls", "1", "--preshapes", "wrap", "--reach-placements", "0", "--workers", "1"]
    for flag, name in (([], "settled.db"), (["--no-settle"], "planned.db")):
        code, _, err = grasp("generate", "box", "--hand", "barrett", "--db", str(tmp_path / name), *small, *flag)
        assert code == 0, err
    code, out, err = grasp("best", "box", "--hand", "barrett", "--db", str(tmp_path / "settled.db"), "--json")
    assert code == 0, err
    assert isinstance(json.loads(out)[0]["settled_epsilon"], float)
    code, out, _ = grasp("best", "box", "--hand", "barrett", "--db", str(tmp_path / "settled.db"))
    assert " settled_epsilon=" in out.splitlines()[0]
    code, out, _ = grasp("best", "box", "--hand", "barrett", "--db", str(tmp_path / "planned.db"), "--json")
    assert json.loads(out)[0]["settled_epsilon"] is None
