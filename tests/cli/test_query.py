"""``grasp best`` and ``grasp show``: the documented JSON, and fingers that really touch."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from helpers import FAST, damaged, grasp, one_line_error

from planner import api


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
    heads = [line for line in out.splitlines() if line.startswith("#")]
    assert len(heads) == 2  # no p_hold model (the tests switch the shipped ones off): n/a
    assert heads[0].startswith("#1 box/panda preshape wide: p_hold n/a (no calibrated model for the hand); score ")
    first = out.split("\n#2")[0]
    assert "object frame: hand base (panda_hand) at (" in first and "tool centre point at (" in first
    assert "orientation xyzw (" in first and "approach direction (" in first and "finger width " in first
    assert " holds " in first and " times its weight in the worst of 14 directions" in first  # analytic measures
    assert "feasibility " in first
    assert "world frame" not in first
    code, out, err = grasp("show", "box", "--hand", "panda", "--db", str(box_db), "--out", str(tmp_path / "g.png"))
    assert code == 0 and (tmp_path / "g.png").stat().st_size > 1000, err


def test_a_grasp_that_is_not_force_closure_says_what_that_means(box_db: Path) -> None:
    from dataclasses import replace

    from planner import api
    from planner.present.describe import describe
    from planner.specs.hands import hand_frame

    top = api.best("box", "panda", db_path=box_db, top=1)[0]
    said = "    not force closure as planned: it ranks after every force-closure grasp"
    assert top.force_closure and not any(x.startswith(said) for x in describe(top, hand_frame("panda")))
    unsqueezed = replace(top.measures, squeezed_force_closure=False, squeezed_epsilon=0.0, squeeze_turn=0.2)
    lines = describe(replace(top, force_closure=False, epsilon=0.0, measures=unsqueezed), hand_frame("panda"))
    assert any("NOT force closure)" in x for x in lines) and any(x.startswith(said) for x in lines), lines
    (where,) = [x for x in lines if x.startswith(said)]  # a parent its stored end stands for may rank after it
    assert "but for those whose squeeze's end stands for them: with them, by score" in where


def test_a_grasp_that_ranks_first_only_once_squeezed_says_why(box_db: Path) -> None:
    """A Panda grasp not force closure as planned but force closure after the squeeze ranks with the force-closure
    grasps (planner.db.ranking.FIRST): `grasp best` says so, not that it ranks after them; where that squeeze's end
    is stored beside it, the end stands for it and it ranks after them: `grasp best` says that."""
    from dataclasses import replace

    from planner import api
    from planner.present.describe import describe
    from planner.specs.hands import hand_frame

    top = api.best("box", "panda", db_path=box_db, top=1)[0]
    squeezed = replace(top.measures, squeezed_force_closure=True, squeezed_epsilon=0.0123, squeeze_turn=0.35)
    lines = describe(replace(top, force_closure=False, epsilon=0.0, measures=squeezed), hand_frame("panda"))
    assert not any("ranks after every force-closure grasp" in x for x in lines), lines
    assert any("NOT force closure as planned, force closure once squeezed" in x for x in lines), lines
    (why,) = [x for x in lines if "once the jaw's squeeze turns the object 20.1 deg" in x]
    assert "squeezed epsilon 0.0123" in why and "ranks with the force-closure grasps" in why
    assert "no end of its squeeze stands for it: none is stored beside it, or the database was ranked before" in why
    lines = describe(replace(top, force_closure=False, epsilon=0.0, measures=squeezed, end_kept=True),
                     hand_frame("panda"))
    (why,) = [x for x in lines if "once the jaw's squeeze turns the object 20.1 deg" in x]
    assert f"stored as a grasp of its own, candidate {top.candidate} too" in why  # where its end is (2026-12-07)
    assert "it stands for this one, which ranks after every force-closure grasp" in why  # and so it ranks
    assert "ranks with the force-closure grasps" not in why
    lines = describe(replace(top, force_closure=False, epsilon=0.0, measures=squeezed, end_kept=True, rank=None),
                     hand_frame("panda"))  # planned on the spot (`best --on-table`): neither it nor its end is stored
    (why,) = [x for x in lines if "once the jaw's squeeze turns the object 20.1 deg" in x]
    assert "end is planned now too as a grasp of its own" in why and "stored" not in why


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


def test_a_mesh_path_names_the_object_stored_from_that_file(tmp_path: Path) -> None:
    """`best a/cube.obj` on an object a manifest stored as 'a/cube' at scale 0.05 said 'no grasps of cube' and
    told the user to generate a new 1 m object; the file of another object named 'cube' gave that one's grasps."""
    import trimesh

    for folder, height in (("a", 1.0), ("b", 1.2)):
        (tmp_path / folder).mkdir()
        trimesh.creation.box(extents=[1.0, 1.0, height]).export(tmp_path / folder / "cube.obj")
    (tmp_path / "both.txt").write_text("a/cube.obj scale=0.05\nb/cube.obj scale=0.05\n")
    (tmp_path / "one.txt").write_text("a/cube.obj scale=0.04\n")
    both, one = tmp_path / "both.db", tmp_path / "one.db"
    for manifest, db in (("both.txt", both), ("one.txt", one)):
        code, _, err = grasp("generate", f"@{tmp_path / manifest}", "--hand", "panda", "--db", str(db), "--quiet",
                             *FAST)
        assert code == 0, err
    code, out, err = grasp("best", str(tmp_path / "a" / "cube.obj"), "--hand", "panda", "--db", str(both), "--json")
    assert code == 0 and json.loads(out)[0]["object"] == "a/cube", err
    code, _, err = grasp("best", str(tmp_path / "b" / "cube.obj"), "--hand", "panda", "--db", str(one))
    one_line_error(code, err, 2, "is not stored in", "its object 'cube' is another file", str(tmp_path / "a"))
    code, _, err = grasp("generate", f"@{tmp_path / 'one.txt'}", "--hand", "panda", "--db", str(both), "--quiet",
                         *FAST)  # the same file at another scale: 'cube'
    assert code == 0, err
    code, _, err = grasp("best", str(tmp_path / "a" / "cube.obj"), "--hand", "panda", "--db", str(both))
    one_line_error(code, err, 2, "as 2 objects, 'a/cube' (scale 0.05), 'cube' (scale 0.04): give the object's name")


@pytest.mark.parametrize("command", [["show", "--out", "x.png"], ["best"], ["best", "--object-pose", "0,0,0,0,0,0,1"]])
def test_an_object_neither_stored_nor_known_is_a_one_line_error(stored_db: Path, command: list[str]) -> None:
    code, _, err = grasp(command[0], "teapot", "--hand", "panda", "--db", str(stored_db), *command[1:])
    one_line_error(code, err, 2, "unknown object 'teapot': not stored in", "(objects: box, capsule, duck)",
                   "not a built-in name, random_NNN or mesh file")


def test_the_barrett_settles_by_default_and_best_prints_its_settled_epsilon(tmp_path: Path) -> None:
    # three rays: force-closure grasps (the ones that settle) and others
    small = ["--approaches", "3", "--rolls", "1", "--preshapes", "wrap", "--reach-placements", "0", "--workers", "1"]
    for flag, name in (([], "settled.db"), (["--no-settle"], "planned.db")):
        code, _, err = grasp("generate", "box", "--hand", "barrett", "--db", str(tmp_path / name), *small, *flag)
        assert code == 0, err
    code, out, err = grasp("best", "box", "--hand", "barrett", "--db", str(tmp_path / "settled.db"), "--json",
                           "--top", "20")
    assert code == 0, err
    ranked = json.loads(out)
    assert ranked[0]["force_closure"] and isinstance(ranked[0]["settled_epsilon"], float)
    assert any(not g["force_closure"] for g in ranked)
    assert all(g["settled_epsilon"] is None for g in ranked if not g["force_closure"])  # only force closure settles
    code, out, _ = grasp("best", "box", "--hand", "barrett", "--db", str(tmp_path / "settled.db"))
    assert "; settled epsilon " in out.split("\n#2")[0]
    code, out, _ = grasp("best", "box", "--hand", "barrett", "--db", str(tmp_path / "planned.db"), "--json")
    assert json.loads(out)[0]["settled_epsilon"] is None


def test_best_gives_the_frames_people_use(box_db: Path) -> None:
    """Object and world frames, hand base and tool centre point, quaternion
    xyzw, approach; JSON keeps them all; arm joints in radians."""
    from scipy.spatial.transform import Rotation

    code, out, err = grasp("best", "box", "--hand", "panda", "--db", str(box_db), "--json")
    assert code == 0, err
    top = json.loads(out)[0]
    pose, frame = np.array(top["pose"]), top["frames"]["object_frame"]
    hand, _ = api.hand("panda")
    assert np.allclose(frame["hand_base_m"], pose[:3, 3])
    assert np.allclose(frame["tcp_m"], pose[:3, :3] @ hand.tcp + pose[:3, 3])
    assert np.allclose(Rotation.from_quat(frame["quaternion_xyzw"]).as_matrix(), pose[:3, :3])
    assert np.allclose(frame["approach"], pose[:3, :3] @ hand.approach)
    at = "0.5,0.1,0.05,0,0,0.7071068,0.7071068"
    code, out, err = grasp("best", "box", "--hand", "panda", "--db", str(box_db), "--object-pose", at,
                           "--max-candidates", "20", "--json")
    assert code == 0, err
    found = json.loads(out)
    assert found, "a reachable grasp among the top 20"
    world = found[0]["frames"]["world_frame"]
    obj = np.eye(4)
    obj[:3, :3] = Rotation.from_quat([0, 0, 0.7071068, 0.7071068]).as_matrix()
    obj[:3, 3] = [0.5, 0.1, 0.05]
    placed = obj @ np.array(found[0]["pose"])
    assert np.allclose(world["hand_base_m"], placed[:3, 3], atol=1e-6)
    assert np.allclose(world["hand_base_m"], np.array(found[0]["hand_pose_world"])[:3, 3], atol=1e-6)
    code, out, err = grasp("best", "box", "--hand", "panda", "--db", str(box_db), "--object-pose", at,
                           "--max-candidates", "20")
    assert code == 0, err
    assert "world frame: hand base (panda_hand) at (" in out and "arm at the grasp [rad]: panda_joint1 " in out


def test_on_table_uses_resting_poses_and_its_pose_reproduces_the_grasp(box_db: Path) -> None:
    code, out, err = grasp("best", "box", "--hand", "panda", "--db", str(box_db), "--on-table", "--stable-poses", "2",
                           "--max-candidates", "30", "--top", "2")
    assert code == 0, err
    blocks = out.split("resting pose ")[1:]
    assert len(blocks) == 2 and blocks[0].startswith("1 of 2 (probability ")
    for block in blocks:  # every pose, not only the first: each is searched as --object-pose searches it
        pose = block.splitlines()[0].split("--object-pose ")[1]
        ranks = [line.split()[0] for line in block.splitlines() if line.startswith("#")]
        code, again, err = grasp("best", "box", "--hand", "panda", "--db", str(box_db), "--object-pose", pose,
                                 "--max-candidates", "30", "--top", "2")
        assert code == 0, err
        assert [line.split()[0] for line in again.splitlines() if line.startswith("#")] == ranks


def test_each_resting_pose_is_searched_from_the_seed(box_db: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The IK restarts of every resting pose start from ``seed``, as ``best_at(..., seed)`` starts: the pose printed
    with ``--object-pose`` repeats the search (a generator shared by the poses gave pose 2 other grasps)."""
    from planner.api import on_table, reaching

    states = []

    def recording(*args, **kwargs):  # type: ignore[no-untyped-def]
        states.append(args[7].bit_generator.state["state"]["state"])
        found = reaching._reachable(*args, **kwargs)
        args[7].random()  # as IK restarts draw: whatever a pose draws, the next starts from the seed
        return found

    monkeypatch.setattr(on_table, "_reachable", recording)
    api.best_on_table("box", "panda", db_path=box_db, poses=2, top=2, max_candidates=30, seed=5)
    assert states == [np.random.default_rng(5).bit_generator.state["state"]["state"]] * 2


@pytest.mark.parametrize("args, flag", [
    (["best", "--table-at", "0.4,0"], "--table-at"), (["best", "--seed", "3"], "--seed"),
    (["best", "--min-translation", "0.1"], "--min-translation"),
    (["validate", "--top", "2", "--all"], "--top"), (["best", "--no-plan"], "--no-plan"),
    (["show", "--rank", "2", "--top", "3"], "--rank"), (["generate", "--stable-poses", "2"], "--stable-poses")])
def test_an_option_that_would_do_nothing_is_refused(box_db: Path, tmp_path: Path, args: list[str], flag: str) -> None:
    db = tmp_path / "copy.db"
    shutil.copy(box_db, db)
    where = [] if args[0] == "validate" else ["box", "--hand", "panda"]
    code, _, err = grasp(args[0], *where, *args[1:], "--db", str(db))
    one_line_error(code, err, 2, f"{flag} does nothing here: ")


def test_an_unreachable_pose_explains_the_miss(box_db: Path) -> None:
    code, _, err = grasp("best", "box", "--hand", "panda", "--db", str(box_db), "--object-pose", "3,0,0.05,0,0,0,1",
                         "--max-candidates", "4")
    one_line_error(code, err, 1, "none of the 4 best grasps of 'box' for hand 'panda' is reachable",
                   "nearest ranks tried #1: ", "of 4 tried: ", "--max-candidates 40")


def test_an_unreachable_pose_with_json_is_the_same_error(box_db: Path) -> None:
    """With --json the same miss printed `[]` and exited 0: a script could not tell "none reachable" from success,
    nor why (the README: exit 1 where `best --object-pose` finds no reachable grasp)."""
    code, out, err = grasp("best", "box", "--hand", "panda", "--db", str(box_db), "--object-pose",
                           "3,0,0.05,0,0,0,1", "--max-candidates", "4", "--json")
    one_line_error(code, err, 1, "none of the 4 best grasps of 'box' for hand 'panda' is reachable",
                   "nearest ranks tried #1: ")
    assert out == "", out


def test_quaternions_match_scipy() -> None:
    from scipy.spatial.transform import Rotation

    from planner.geometry.quaternion import canonical_xyzw, quaternion_xyzw

    rotations = Rotation.random(200, random_state=4).as_matrix()
    turns = [Rotation.from_rotvec(v).as_matrix() for v in np.pi * np.eye(3)]  # half turns: w = 0
    for r in [*rotations, *turns, np.eye(3)]:
        q = canonical_xyzw(r)
        assert np.allclose(Rotation.from_quat(q).as_matrix(), r, atol=1e-12)
        assert np.isclose(np.linalg.norm(q), 1.0) and q[3] >= 0
        assert np.allclose(Rotation.from_quat(quaternion_xyzw(r)).as_matrix(), r, atol=1e-12)  # the simulators'
        assert np.isclose(np.linalg.norm(quaternion_xyzw(r)), 1.0, atol=1e-12)


def test_hand_frame_reads_what_load_hand_reads() -> None:
    from planner.specs.hands import hand_frame, hand_names, load_hand

    for name in hand_names():
        light, full = hand_frame(name), load_hand(name)
        assert light.root_link == full.root_link
        assert np.allclose(light.tcp, full.tcp) and np.allclose(light.approach, full.approach)
@pytest.mark.parametrize("command", [["best", "box", "--hand", "panda"], ["export", "--format", "csv", "--out", "OUT"],
                                     ["validate", "--workers", "1"]])
def test_a_damaged_database_is_a_one_line_error(box_db: Path, tmp_path: Path, command: list[str]) -> None:
    broken = damaged(box_db, tmp_path / "broken.db")
    args = [str(tmp_path / "out") if a == "OUT" else a for a in command]
    code, _, err = grasp(*args, "--db", str(broken))
    one_line_error(code, err, 3, "grasp: error:", "cannot read the database", "grasp db check")


def test_explain_gives_the_rule_term_by_term(box_db: Path) -> None:
    code, out, err = grasp("best", "box", "--hand", "panda", "--db", str(box_db), "--top", "2", "--explain", "--json")
    assert code == 0, err

    def not_json(token: str) -> None:
        raise AssertionError(f"{token} is not JSON")

    for item in json.loads(out, parse_constant=not_json):  # strict JSON: NaN of a term not taken is null
        terms = item["frames"]["explain"]
        assert terms["p_hold"] is None and terms["p_hold_trial"] is None  # no model in the test's database
        assert terms["score"] == pytest.approx(item["score"], rel=1e-9, abs=1e-12)
        assert terms["score"] == pytest.approx(terms["analytic"] * terms["reach_factor"] * terms["success_factor"])
        rule = api.ranking_rule(box_db)
        if_gated = terms["press"] * (1 + terms["hold"]) / 2 + rule.eps_weight * terms["quality"] \
            + rule.settled_weight * terms["settled"]
        assert terms["analytic"] == pytest.approx(terms["gate"] * if_gated)
    code, out, err = grasp("best", "box", "--hand", "panda", "--db", str(box_db), "--explain")
    assert code == 0, err
    assert "why this score" in out and "gate 1: open margin " in out and "= analytic " in out and "= score " in out


@pytest.mark.parametrize("p, shown", [(0.99999, ">0.999"), (0.9994, ">0.999"), (0.999, "0.999"), (1.0, "1.000"),
                                      (0.5, "0.500"), (0.0004, "<0.001"), (0.0, "0.000"), (0.0015, "0.002")])
def test_p_hold_is_never_printed_as_a_certainty_it_is_not(p, shown) -> None:  # type: ignore[no-untyped-def]
    from planner.present.describe import probability

    assert probability(p) == shown


def test_a_pose_through_the_table_is_refused(box_db: Path) -> None:
    """The box's origin is its centre: at z = 0 it sinks 4 cm into the table top."""
    code, _, err = grasp("best", "box", "--hand", "panda", "--db", str(box_db), "--object-pose", "0.5,0,0,0,0,0,1")
    one_line_error(code, err, 2, "--object-pose puts box through the table", "40.0 mm below the table top",
                   f"`grasp best box --hand panda --db {box_db} --on-table`")


@pytest.mark.parametrize("score, shown", [(1.02, "1.0200"), (0.9985, "0.9985"), (0.99994, "0.9999"),
                                          (0.99998, "1 - 2e-05"), (0.9999987, "1 - 1.3e-06"), (1.0, "1.0000")])
def test_scores_just_below_1_are_printed_in_their_order(score: float, shown: str) -> None:
    from planner.present.describe import score_text

    assert score_text(score) == shown


def test_best_says_when_its_ranks_predate_stored_trial_verdicts(box_db: Path, tmp_path: Path) -> None:
    """A `grasp validate` killed before it re-ranked leaves the pair marked (meta.unranked): `best` then
    printed grasps its trials saw drop as the best without a word."""
    import sqlite3

    db = tmp_path / "g.db"
    shutil.copy(box_db, db)
    code, out, err = grasp("best", "box", "--hand", "panda", "--db", str(db))
    assert code == 0 and "predate trial verdicts" not in err, err
    with sqlite3.connect(db) as conn:
        conn.execute("INSERT INTO meta (key, value) VALUES ('unranked', ?)", ('[["box", "panda"]]',))
    conn.close()
    code, out, err = grasp("best", "box", "--hand", "panda", "--db", str(db))
    assert code == 0 and out.startswith("#1 box/panda"), err
    assert "note: the ranks of box's panda grasps predate trial verdicts" in err and f"--db {db}` re-ranks" in err
    for pose in ([], ["--object-pose", "0.5,0,0.04,0,0,0,1"]):  # with --json: said on stderr as well (was silent)
        code, out, err = grasp("best", "box", "--hand", "panda", "--db", str(db), "--json", *pose)
        assert code == 0 and json.loads(out), err
        assert "note: the ranks of box's panda grasps predate trial verdicts" in err, (pose, err)


def test_a_held_grasp_that_cannot_hold_its_weight_in_every_direction_says_why_both_hold() -> None:
    """The quick start's best mug grasp read 'cannot_hold_weight', 'p_hold >0.999' and 'MuJoCo trial: held (held)'
    with nothing to tell the user which to trust: the trial loads one direction, the flag is the worst of 14."""
    from dataclasses import replace

    from planner.present.describe import describe
    from planner.record.grasp import Trial
    from planner.record.measures import Measures
    from planner.specs.hands import load_hand
    from tests.helpers import made_up

    weak = Measures(0.2, 5.2, 0.01, 0.01, 0.97, ("cannot_hold_weight",))
    held, dropped = Trial(True, 2, 0.001, 0.01, 0.002, 0.02, "held"), Trial(False, 1, 0.03, 0.2, 0.1, 0.5, "slipped")
    lines = describe(replace(made_up(1, 0.01), measures=weak, mujoco=held), load_hand("panda"))
    assert "    MuJoCo trial: held" in lines and not any("(held)" in line for line in lines)
    assert any(line.startswith("    its weight: the MuJoCo trial held it loaded along one direction") and
               "worst of 14 directions, where the fingers' force limits hold 0.2 times its weight" in line
               for line in lines)
    lines = describe(replace(made_up(1, 0.01), measures=weak, mujoco=dropped), load_hand("panda"))
    assert "    MuJoCo trial: dropped (slipped)" in lines and not any("its weight:" in line for line in lines)


def test_an_untried_grasp_that_cannot_hold_its_weight_in_every_direction_says_what_each_figure_means() -> None:
    """The quick start's `grasp best` printed the mug's #1 grasp with 'p_hold >0.999' and 'feasibility
    cannot_hold_weight' at once and nothing more (the line saying why both can be true came only after a trial held
    it): the flag is the worst of 14 directions of the weight, p_hold is of a load along the object's down."""
    from dataclasses import replace

    from planner.present.describe import describe
    from planner.record.measures import Measures
    from planner.specs.hands import load_hand
    from tests.helpers import made_up

    weak = Measures(0.2, 5.2, 0.01, 0.01, 0.97, ("cannot_hold_weight",))
    lines = describe(replace(made_up(1, 0.01), measures=weak, p_hold=0.9995), load_hand("panda"))
    said = [line for line in lines if line.startswith("    its weight: ")]
    assert len(said) == 1 and "worst of 14 directions about the hand the fingers' force limits hold 0.2 times it" \
        in said[0] and "p_hold says how often labelled grasps" in said[0] and "not tried yet" in said[0], lines
    assert "loads it along the object's down, +y," in describe(replace(made_up(1, 0.01), measures=weak),
                                                             load_hand("panda"), up="-y")[-1]
    no_model = describe(replace(made_up(1, 0.01), measures=weak, p_hold=None), load_hand("panda"))[-1]
    assert no_model.startswith("    its weight: ") and "p_hold" not in no_model


def test_a_grasp_flagged_cannot_hold_weight_is_never_said_to_hold_its_weight_once() -> None:
    """A worst-direction resistance of 0.96 (under the flag's 1.0) was printed "holds 1.0 times its weight" and "the
    fingers' force limits hold 1.0 times it" beside feasibility cannot_hold_weight."""
    from dataclasses import replace

    from planner.present.describe import describe, times_weight
    from planner.record.measures import Measures
    from planner.specs.hands import load_hand
    from tests.helpers import made_up

    assert [times_weight(r) for r in (0.94, 0.96, 0.999, 1.0, 1.04)] == ["0.9", "0.96", "0.99", "1.0", "1.0"]
    weak = Measures(0.96, 5.2, 0.01, 0.01, 0.97, ("cannot_hold_weight",))
    text = "\n".join(describe(replace(made_up(1, 0.01), measures=weak, p_hold=0.9995), load_hand("panda")))
    assert "holds 0.96 times its weight" in text and "force limits hold 0.96 times it" in text, text
    assert "1.0 times" not in text, text


def test_a_coordinate_that_rounds_to_zero_is_printed_without_a_sign(box_db: Path) -> None:
    """`grasp best` printed "(0.021, -0.000, 0.109)" and its JSON -0.0 where a value lay a hair below zero."""
    from dataclasses import replace

    from planner import api
    from planner.present.describe import Frames, describe, frame_lines
    from planner.specs.hands import hand_frame

    tiny = np.array([-1e-9, -0.0, 0.5])
    f = Frames("object", tiny, tiny, np.array([-0.0, -1e-7, -0.0, 1.0]), tiny)
    line = frame_lines(f, hand_frame("panda"))[0]
    assert "-0.0" not in line and "(0.000, 0.000, 0.500)" in line, line
    assert "-0.0" not in json.dumps(f.to_json())
    top = api.best("box", "panda", db_path=box_db, top=1)[0]
    arm = {"the grasp": {"j1": -1e-6, "j2": -0.25}}
    said = [x for x in describe(replace(top), hand_frame("panda"), arm=arm) if "arm at" in x]
    assert said == ["    arm at the grasp [rad]: j1 0.0000, j2 -0.2500"]


def test_a_weight_resistance_at_the_measures_cap_is_said_as_a_bound(box_db: Path) -> None:
    """A Barrett grasp "holds 50.0 times its weight ... (mean 50.0)": 50 is where the measure stops."""
    from dataclasses import replace

    from planner import api
    from planner.present.describe import describe
    from planner.quality.tolerances import RESISTANCE_CAP
    from planner.specs.hands import hand_frame

    top = api.best("box", "panda", db_path=box_db, top=1)[0]
    capped = replace(top, measures=replace(top.measures, resist_worst=RESISTANCE_CAP, resist_mean=RESISTANCE_CAP))
    line = next(x for x in describe(capped, hand_frame("panda")) if " holds " in x)
    assert line.startswith("    holds at least 50 times its weight (the measure's cap) in the worst of 14 directions "
                           "(mean at least 50); "), line
    below = replace(top, measures=replace(top.measures, resist_worst=12.34, resist_mean=20.0))
    assert "    holds 12.3 times its weight in the worst of 14 directions (mean 20.0); " in describe(
        below, hand_frame("panda"))[3]


def test_show_of_a_rank_past_the_last_says_how_many_there_are(box_db: Path, tmp_path: Path) -> None:
    """`grasp show --rank 5000` on a database with fewer grasps said "no grasp of rank 5000", not how many."""
    stored = len(api.best("box", "panda", db_path=box_db, top=100_000))
    code, _, err = grasp("show", "box", "--hand", "panda", "--db", str(box_db), "--rank", "5000",
                         "--out", str(tmp_path / "s.png"))
    one_line_error(code, err, 2, "no grasp of rank 5000", f"it has {stored} (--rank 1 to {stored})")
    assert not (tmp_path / "s.png").exists()


def test_show_of_a_diverse_rank_past_the_last_says_how_many_diverse_there_are(box_db: Path, tmp_path: Path) -> None:
    """`grasp show --diverse --rank K` past the last diverse grasp said "it has N (--rank 1 to N)" with N every
    stored grasp: --rank N failed the same way. It says how many diverse ones there are."""
    from planner.db.diverse import Spacing

    diverse = len(api.best("box", "panda", db_path=box_db, top=100_000, spacing=Spacing()))
    assert diverse < len(api.best("box", "panda", db_path=box_db, top=100_000))
    code, _, err = grasp("show", "box", "--hand", "panda", "--db", str(box_db), "--diverse", "--rank",
                         str(diverse + 1), "--out", str(tmp_path / "s.png"))
    one_line_error(code, err, 2, f"no grasp of rank {diverse + 1}", f"it has {diverse} diverse ones (--rank 1 to "
                   f"{diverse})")


@pytest.mark.parametrize("as_json", [False, True])
def test_best_at_a_pose_says_which_better_ranks_it_left_out(box_db: Path, monkeypatch: pytest.MonkeyPatch,
                                                            as_json: bool) -> None:
    """`grasp best mug --object-pose ... --top 2` printed #2 and #3 and nothing about #1: the ranks tried and not
    reached are said under the grasps, as a miss says them; with --json on stderr (said nowhere until 2026-12-07),
    stdout one JSON document."""
    from planner import api

    real = api.best_at

    def best_at(*args, misses, **kwargs):  # type: ignore[no-untyped-def]
        found = real(*args, misses=misses, **kwargs)
        misses.insert(0, (1, "no IK solution for the grasp"))  # as if the best one were out of the arm's reach
        return found

    monkeypatch.setattr(api, "best_at", best_at)
    code, out, err = grasp("best", "box", "--hand", "panda", "--db", str(box_db), "--object-pose",
                           "0.5,0,0.05,0,0,0,1", "--max-candidates", "20", *(["--json"] if as_json else []))
    assert code == 0, err
    [note] = [line for line in (err if as_json else out).splitlines()
              if line.startswith("note: stored grasps the arm does not reach")]
    assert "#1: no IK solution for the grasp" in note
    assert ("note: stored grasps" in out) is not as_json  # with --json stdout is the list alone


def test_show_makes_a_missing_folder_only_when_it_writes_and_says_so(box_db: Path, tmp_path: Path) -> None:
    """`grasp show --out /new/dir/x.png` made the folder without a word (a mistyped folder went unseen). As every
    --out of the project (export's folder, report's, calibrate's --model-out and --plot), a missing folder is made,
    now said; a refused show makes none, and the help says what happens."""
    code, _, err = grasp("show", "box", "--hand", "panda", "--db", str(box_db), "--rank", "5000",
                         "--out", str(tmp_path / "refused" / "deeper" / "s.png"))
    assert code == 2 and not (tmp_path / "refused").exists(), err
    out_png = tmp_path / "new" / "deeper" / "s.png"
    code, out, err = grasp("show", "box", "--hand", "panda", "--db", str(box_db), "--out", str(out_png))
    assert code == 0 and out_png.stat().st_size > 1000, err
    assert out.strip() == f"{out_png}: 1 grasp(s) from 3 viewpoints (made the folder {tmp_path / 'new'})", out
    code, out, err = grasp("show", "box", "--hand", "panda", "--db", str(box_db), "--out", str(out_png))
    assert code == 0 and "made the folder" not in out, out
    for command, option in (("show", "--out"), ("report", "--out"), ("calibrate", "--model-out"),
                            ("calibrate", "--plot")):
        code, out, _ = grasp(command, "--help")
        said = " ".join(out.split())
        assert code == 0 and "missing" in said[said.index(option):][:200], (command, option, said)


def test_best_with_another_hand_than_the_object_was_swept_with_names_its_hands(box_db: Path) -> None:
    """`grasp best box --hand barrett` on a database of the Panda's box grasps said "objects with grasps: (none)",
    as if the database were empty, and told to sweep again: the hand asked was the mistake."""
    code, _, err = grasp("best", "box", "--hand", "barrett", "--db", str(box_db))
    one_line_error(code, err, 2, "no grasps of 'box' for hand 'barrett'", "'box' has grasps for panda (--hand)")
    assert "objects with grasps: (none)" not in err and "objects with grasps for barrett: (none)" in err, err
