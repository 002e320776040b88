"""The whole path through the ``grasp`` command, and its error contract."""

import json
import sqlite3
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from planner.cli import main

FAST = ["--approaches", "6", "--rolls", "2", "--preshapes", "wide", "--workers", "1"]


def run(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(main, list(args))
    return result.exit_code, result.stdout, result.stderr


@pytest.fixture(scope="module")
def box_db(tmp_path_factory: pytest.TempPathFactory) -> Path:
    db = tmp_path_factory.mktemp("cli") / "g.db"
    code, out, err = run("generate", "box", "--hand", "panda", "--db", str(db), "--quiet", *FAST)
    assert code == 0, err
    return db


def test_best_json_has_the_documented_keys(box_db: Path) -> None:
    code, out, err = run("best", "box", "--hand", "panda", "--db", str(box_db), "--top", "3", "--json")
    assert code == 0, err
    grasps = json.loads(out)
    assert 1 <= len(grasps) <= 3
    keys = {"object", "hand", "preshape", "pose", "joints", "epsilon", "volume", "force_closure", "contacts", "rank",
            "score"}
    assert keys <= set(grasps[0])
    assert [g["rank"] for g in grasps] == list(range(1, len(grasps) + 1))
    pose = np.array(grasps[0]["pose"])
    assert pose.shape == (4, 4) and np.allclose(pose[:3, :3] @ pose[:3, :3].T, np.eye(3), atol=1e-6)
    assert grasps[0]["epsilon"] > 0 and grasps[0]["force_closure"]
    assert {"point", "normal", "link"} <= set(grasps[0]["contacts"][0])


def test_generate_json_summary(tmp_path: Path) -> None:
    code, out, err = run("generate", "sphere", "--hand", "panda", "--db", str(tmp_path / "s.db"), "--json", *FAST)
    assert code == 0, err
    summary = json.loads(out)
    assert summary["candidates"] == 6 * 2 * 2 and summary["units"] == 1


def test_lists() -> None:
    code, out, _ = run("hands")
    assert code == 0 and "panda" in out
    code, out, _ = run("objects")
    assert code == 0 and all(n in out for n in ("mug", "duck", "teddy", "bunny", "box", "cylinder", "sphere"))


@pytest.mark.parametrize("args, code, message", [
    (["generate", "teapot", "--hand", "panda"], 2, "unknown object 'teapot'"),
    (["generate", "box", "--hand", "robotiq"], 2, "unknown hand 'robotiq'. Available hands:"),
    (["generate", "missing.obj", "--hand", "panda"], 2, "missing.obj: file not found"),
    (["generate", "box", "--hand", "panda", "--preshapes", "fist"], 2, "unknown preshape 'fist'"),
    (["best", "box", "--hand", "panda", "--db", "nowhere.db"], 3, "no such database"),
])
def test_bad_input_is_one_line_and_exit_code(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, args: list[str],
                                             code: int, message: str) -> None:
    monkeypatch.chdir(tmp_path)
    got, out, err = run(*args)
    assert got == code
    assert message in err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err


def test_broken_mesh_leaves_existing_database_untouched(box_db: Path, tmp_path: Path) -> None:
    before = box_db.read_bytes() if not Path(str(box_db) + "-wal").exists() else None
    rows = sqlite3.connect(box_db).execute("SELECT COUNT(*) FROM grasps").fetchone()[0]
    bad = tmp_path / "broken.obj"
    bad.write_text("v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n")
    code, _, err = run("generate", str(bad), "--hand", "panda", "--db", str(box_db), "--quiet", *FAST)
    assert code == 2 and "broken" in err
    assert sqlite3.connect(box_db).execute("SELECT COUNT(*) FROM grasps").fetchone()[0] == rows
    if before is not None:
        assert box_db.read_bytes() == before


def test_not_a_database_is_refused(tmp_path: Path) -> None:
    junk = tmp_path / "junk.db"
    junk.write_text("hello")
    code, _, err = run("generate", "box", "--hand", "panda", "--db", str(junk), *FAST)
    assert code == 3 and "not an SQLite database" in err
    assert junk.read_text() == "hello"


def test_db_check(box_db: Path) -> None:
    code, out, _ = run("db", "check", "--db", str(box_db))
    assert code == 0 and "ok" in out


def test_best_grasp_fingers_really_touch_the_object(box_db: Path) -> None:
    """Re-place the hand from the JSON alone and measure the true finger gaps."""
    from planner.geometry.solid import load_object
    from planner.sim import Sim
    from planner.specs.hands import load_hand

    code, out, err = run("best", "box", "--hand", "panda", "--db", str(box_db), "--json")
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
