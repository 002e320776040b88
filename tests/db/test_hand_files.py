"""A database records the files of the hand its grasps were made with, and
refuses to store, validate or import grasps of an edited hand under the
same name (planner.db.hand_files)."""

from __future__ import annotations

import json
import shutil
import sqlite3
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import pytest

from planner import assets
from planner.db.hand_files import META_KEY, changed_by_project, check_hand_files, refuse_edited
from planner.db.ranking import RankingRule
from planner.db.store import UnitRow, open_for_writing
from planner.errors import InputError
from planner.geometry.solid import load_object
from planner.specs.hand_files import changed, hand_files
from planner.specs.hands import hand_frame, load_hand
from tests.helpers import content, grasp, made_up, one_line_error


@pytest.fixture
def project(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """A project folder holding copies of the Panda's, the Allegro's and the PR2's hand and preshapes."""
    root = tmp_path / "project"
    for hand in ("panda", "allegro", "pr2"):
        shutil.copytree(assets.PROJECT_ROOT / "hands" / hand, root / "hands" / hand)
        (root / "preshapes").mkdir(parents=True, exist_ok=True)
        shutil.copy(assets.PROJECT_ROOT / "preshapes" / f"{hand}.toml", root / "preshapes")
    shutil.copytree(assets.PROJECT_ROOT / "objects", root / "objects")
    monkeypatch.setattr(assets, "PROJECT_ROOT", root)
    forget_hands()
    yield root
    forget_hands()


def forget_hands() -> None:
    """Drop every cached reading of a hand's files (the hand, and the frame `best` reads without loading it):
    left cached, the copies' edits leaked into the tests that run after these (the Panda's tcp)."""
    load_hand.cache_clear()
    hand_frame.cache_clear()


def edit(path: Path, old: str, new: str) -> None:
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new, 1))


def test_the_files_of_a_hand_and_what_counts_as_an_edit(project: Path) -> None:
    before = hand_files("panda")
    assert {"hands/panda/hand.toml", "preshapes/panda.toml", "pybullet_data:franka_panda/panda.urdf",
            "pybullet_data:franka_panda/meshes/collision/finger.obj"} <= set(before)
    toml = project / "hands" / "panda" / "hand.toml"
    with toml.open("a") as fh:
        fh.write("\n# a comment\n")
    edit(toml, 'description = "', 'description = "edited: ')
    assert hand_files("panda") == before  # comments, layout and the description do not count
    edit(toml, "tcp = [0.0, 0.0, 0.1034]", "tcp = [0.0, 0.0, 0.1040]")
    assert changed(before, hand_files("panda")) == ["hands/panda/hand.toml"]
    allegro = hand_files("allegro")
    with (project / "hands" / "allegro" / "palm.obj").open("a") as fh:  # a collision mesh, by its bytes
        fh.write("\n")
    assert changed(allegro, hand_files("allegro")) == ["hands/allegro/palm.obj"]
    edit(project / "preshapes" / "allegro.toml", "[[preshape]]", "[[preshape]]\n# moved\n")
    assert changed(allegro, hand_files("allegro")) == ["hands/allegro/palm.obj"]
    # what does not mix two hands: a preshape added, text fields, 70 for 70.0, the URDF's comments and line ends
    panda = hand_files("panda")
    with (project / "preshapes" / "panda.toml").open("a") as fh:
        fh.write('\n[[preshape]]\nname = "new"\ntaxonomy = "x"\njoints = { panda_finger_joint1 = 0.03 }\n')
    edit(project / "preshapes" / "panda.toml", 'taxonomy = "Feix: prismatic', 'taxonomy = "Feix, edited: prismatic')
    assert changed(panda, hand_files("panda")) == []
    urdf = project / "hands" / "allegro" / "allegro.urdf"
    before = hand_files("allegro")
    urdf.write_bytes(urdf.read_bytes().replace(b"\n", b"\r\n").replace(b"<robot", b"<!-- a note -->\n<robot", 1))
    assert changed(before, hand_files("allegro")) == []


def swept(db_path: Path) -> None:
    """A database holding one finished unit of the Panda, the hand's files recorded."""
    with open_for_writing(db_path) as db:
        check_hand_files(db, ["panda"])
        db.write_unit(UnitRow("box", "panda", "h" * 16, json.dumps({}), 5, 0, None, candidates=3), load_object("box"),
                      [replace(made_up(i, 0.05), object="box") for i in range(2)], RankingRule())


def test_an_edited_hand_is_refused_by_every_writer_and_nothing_is_written(project: Path, tmp_path: Path) -> None:
    db_path = tmp_path / "g.db"
    swept(db_path)
    with open_for_writing(db_path) as db:
        check_hand_files(db, ["panda"])  # the same files: accepted
    before = content(db_path)
    edit(project / "preshapes" / "panda.toml", "standoffs = [0.0, 0.02]", "standoffs = [0.0, 0.03]")
    forget_hands()
    for args in (["generate", "box", "--hand", "panda"], ["validate", "--top", "1"]):
        code, _, err = grasp(*args, "--db", str(db_path))
        one_line_error(code, err, InputError.exit_code, "hand 'panda' was edited since g.db",
                       "preshapes/panda.toml [wide] changed", "--db")
    assert content(db_path) == before
    with sqlite3.connect(db_path) as conn:  # the record still names the files the grasps were made with
        stored = json.loads(conn.execute("SELECT value FROM meta WHERE key = ?", (META_KEY,)).fetchone()[0])
    conn.close()
    assert changed(stored["panda"], hand_files("panda")) == ["preshapes/panda.toml [wide]"]
    with open_for_writing(tmp_path / "other.db") as db:  # another database takes the edited hand
        check_hand_files(db, ["panda"])
        assert json.loads(db.meta(META_KEY) or "{}")["panda"] == hand_files("panda")


def test_an_edited_hand_is_refused_where_stored_joints_meet_its_geometry_and_noted_by_best(
        project: Path, tmp_path: Path) -> None:
    """show and best --object-pose put the stored joint values on the edited hand's links without a word (a
    longer finger drawn, reach checked on geometry never planned); best's numbers are the stored grasps: a note."""
    db_path = tmp_path / "g.db"
    swept(db_path)
    edit(project / "hands" / "panda" / "hand.toml", "tcp = [0.0, 0.0, 0.1034]", "tcp = [0.0, 0.0, 0.1040]")
    forget_hands()
    db = ["--db", str(db_path)]
    for args, doing in ((["show", "box", "--hand", "panda", "--out", str(tmp_path / "a.png")], "the picture"),
                        (["best", "box", "--hand", "panda", "--object-pose", "0.5,0,0.04,0,0,0,1"], "the reach check"),
                        (["best", "box", "--hand", "panda", "--on-table"], "the table check")):
        code, _, err = grasp(*args, *db)
        one_line_error(code, err, InputError.exit_code, "hand 'panda' was edited since g.db",
                       "hands/panda/hand.toml changed", doing)
    assert not (tmp_path / "a.png").exists()
    code, out, err = grasp("best", "box", "--hand", "panda", *db)
    assert code == 0 and out.startswith("#1") and "note: hand 'panda' was edited since" in err


def test_a_database_without_grasps_of_the_hand_or_without_a_record_takes_its_files(project: Path,
                                                                                   tmp_path: Path) -> None:
    db_path = tmp_path / "g.db"
    with open_for_writing(db_path) as db:
        check_hand_files(db, ["panda"])  # recorded, but no grasp of the hand stored yet
    edit(project / "hands" / "panda" / "hand.toml", "tcp = [0.0, 0.0, 0.1034]", "tcp = [0.0, 0.0, 0.1040]")
    with open_for_writing(db_path) as db:
        check_hand_files(db, ["panda"])
        assert json.loads(db.meta(META_KEY) or "{}")["panda"] == hand_files("panda")
    old = tmp_path / "old.db"  # written before the record existed: the files as they are at its next write
    swept(old)
    with open_for_writing(old) as db:
        db.set_meta(META_KEY, "{}")
        check_hand_files(db, ["panda"])
        assert json.loads(db.meta(META_KEY) or "{}") == {"panda": hand_files("panda")}
    with open_for_writing(old) as db, pytest.raises(InputError, match="allegro"):
        db.write_unit(UnitRow("thing", "allegro", "h" * 16, json.dumps({}), 5, 0, None), None, [], RankingRule())
        check_hand_files(db, ["allegro"])
        with (project / "hands" / "allegro" / "palm.obj").open("a") as fh:
            fh.write("\n")
        check_hand_files(db, ["panda", "allegro"])


def test_the_projects_same_hand_changes_name_the_files_as_shipped_now() -> None:
    """A declaration of a shipped hand's earlier file as the same hand holds for the file as shipped now only: a
    change to that file again fails here until it is declared (or its databases are meant to be refused)."""
    from planner.specs.hand_files import SAME_HAND

    for label, (shipped, earlier) in SAME_HAND.items():
        hand = label.split("/")[1]
        assert hand_files(hand)[label] == shipped, label
        assert shipped not in earlier and earlier


@pytest.mark.parametrize("hand, file, digest, before, after", [
    ("allegro", "hand.toml", "5386eec9e1cb2ab7", "settle = true", "settle = false"),  # before its settle
    ("allegro", "hand.toml", "6806297ce4d71df3", "closing_speed = 7.0", "closing_speed = 6.0"),  # before 7 rad/s
    ("allegro", "allegro.urdf", "4d5a553ee1ac0fac", 'velocity="7"', 'velocity="8"'),  # its URDF's 6 rad/s
    ("pr2", "hand.toml", "5f6f243e9fb20f0e", "effort = 3.15", "effort = 3.2"),  # before its motors and inertias
    ("pr2", "hand.toml", "5782d429c3d41b3b", 'width_links = ["left_tip", "right_tip"]',
     'width_links = ["right_tip", "left_tip"]'),
])
def test_a_database_made_before_a_declared_change_reads_shows_and_validates_as_before(
        project: Path, tmp_path: Path, hand: str, file: str, digest: str, before: str, after: str) -> None:
    """settle = true in the Allegro's hand.toml (2026-12-06) made every Allegro database made before it 'edited':
    show and validate refused it, telling the user to restore files they never changed; the PR2's motors and
    finger inertias as they are (2026-12-06), then its width_links (2026-12-06), and the Allegro's closing at its
    joints' 7 rad/s (hand.toml and its URDF, 2026-12-06) would have done the same. The project's declared change is
    not an edit, whichever earlier file the database records; the same file edited any further still is."""
    from planner.specs.hand_files import SAME_HAND

    label = f"hands/{hand}/{file}"
    shipped, earlier = SAME_HAND[label]
    assert digest in earlier
    db_path = tmp_path / "g.db"
    with open_for_writing(db_path) as db:
        check_hand_files(db, [hand])
        db.write_unit(UnitRow("box", hand, "h" * 16, json.dumps({}), 5, 0, None, candidates=3),
                      load_object("box"), [replace(made_up(i, 0.05), object="box", hand=hand) for i in range(2)],
                      RankingRule())
        files = json.loads(db.meta(META_KEY))
        files[hand][label] = digest  # as a database of the hand before the change records it
        db.set_meta(META_KEY, json.dumps(files, sort_keys=True))
    now = hand_files(hand)
    assert now[label] == shipped and changed(files[hand], now) == []
    with open_for_writing(db_path) as db:
        check_hand_files(db, [hand])  # validate, generate and import go on (the sweep rule judges a re-run)
    with open_for_writing(db_path) as db:
        refuse_edited(db, hand, "the picture")  # what show and best --object-pose ask
        assert changed_by_project(db, hand) == [f"{label}, {earlier[files[hand][label]]}"]  # best's note says it
    edit(project / "hands" / hand / file, before, after)
    forget_hands()
    assert changed(files[hand], hand_files(hand)) == [label]
    with pytest.raises(InputError, match="was edited since"), open_for_writing(db_path) as db:
        check_hand_files(db, [hand])


def test_an_allegro_database_made_before_it_closed_at_7_rad_s_reads_and_best_notes_both_files(
        project: Path, tmp_path: Path) -> None:
    """A database of the Allegro made before 2026-12-06's closing speed records both its hand.toml and its URDF
    (velocity 6) as they were: both are the project's declared changes, and `best` notes both."""
    from planner.specs.hand_files import SAME_HAND

    before = {"hands/allegro/hand.toml": "6806297ce4d71df3", "hands/allegro/allegro.urdf": "4d5a553ee1ac0fac"}
    db_path = tmp_path / "g.db"
    with open_for_writing(db_path) as db:
        check_hand_files(db, ["allegro"])
        db.write_unit(UnitRow("box", "allegro", "h" * 16, json.dumps({}), 5, 0, None, candidates=3),
                      load_object("box"), [replace(made_up(i, 0.05), object="box", hand="allegro") for i in range(2)],
                      RankingRule())
        files = json.loads(db.meta(META_KEY))
        files["allegro"].update(before)
        db.set_meta(META_KEY, json.dumps(files, sort_keys=True))
    with open_for_writing(db_path) as db:
        check_hand_files(db, ["allegro"])
        refuse_edited(db, "allegro", "the picture")
        assert changed_by_project(db, "allegro") == [f"{label}, {SAME_HAND[label][1][digest]}"
                                                     for label, digest in sorted(before.items())]
