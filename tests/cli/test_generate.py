"""``grasp generate``: summaries, and bad meshes refused with one line while
an existing database is left untouched."""

from __future__ import annotations

import json
import shutil
import sqlite3
import subprocess
import sys
import warnings
from pathlib import Path

import pytest
import trimesh
from helpers import FAST, grasp, one_line_error


def snapshot(db: Path) -> list[tuple]:
    with sqlite3.connect(db) as conn:
        return conn.execute("SELECT * FROM grasps ORDER BY id").fetchall()


def test_generate_json_summary(tmp_path: Path) -> None:
    code, out, err = grasp("generate", "sphere", "--hand", "panda", "--db", str(tmp_path / "s.db"), "--json", *FAST)
    assert code == 0, err
    summary = json.loads(out)
    assert summary["candidates"] == 6 * 2 * 2 and summary["units"] == 1


def test_the_summary_says_how_many_force_closure_grasps_are_squeezes_ends(tmp_path: Path) -> None:
    """The mug's force-closure grasps include the squeezes' ends kept beside their parents (planner.plan.keeping):
    the table, the summary line and --json say how many, as the database holds them."""
    db = tmp_path / "m.db"
    mug = ("generate", "mug", "--hand", "panda", "--approaches", "60", "--rolls", "2", "--reach-placements", "0",
           "--seed", "3", "--workers", "1")
    code, out, err = grasp(*mug, "--db", str(db))
    assert code == 0, err
    with sqlite3.connect(db) as conn:
        fc, ends = conn.execute("SELECT SUM(force_closure), SUM(squeezed_from_turn IS NOT NULL) FROM grasps").fetchone()
    assert 0 < ends < fc
    assert f"force-closure: {fc} ({ends} of them squeezes' ends, each beside its parent)" in " ".join(out.split())
    assert f"{fc} ({ends} ends)" in out  # the object's row
    code, out, err = grasp(*mug, "--db", str(tmp_path / "j.db"), "--json")
    assert code == 0, err
    summary = json.loads(out)
    assert (summary["force_closure"], summary["ends"]) == (fc, ends) == (summary["objects"][0]["force_closure"],
                                                                        summary["objects"][0]["ends"])


def test_fc_budget_stops_an_object_early(tmp_path: Path) -> None:
    runs = {}
    for budget in ("0", "1"):
        code, out, err = grasp("generate", "box", "--hand", "panda", "--db", str(tmp_path / f"b{budget}.db"),
                               "--json", "--fc-budget", budget, *FAST)
        assert code == 0, err
        runs[budget] = json.loads(out)
    assert runs["0"]["force_closure"] > runs["1"]["force_closure"] >= 1
    assert runs["1"]["rejected"]["budget"] == runs["0"]["candidates"] - runs["1"]["candidates"] > 0
    assert "budget" not in runs["0"]["rejected"]


def test_generate_json_on_stdout_is_json_alone_with_worker_processes(tmp_path: Path) -> None:
    """The real command, two worker processes: nothing but the JSON summary on
    standard output (HiGHS prints a banner on fd 1 the first time a process
    makes a solver, which once came before the summary)."""
    args = [a if a != "1" or prev != "--workers" else "2" for prev, a in zip([""] + FAST, FAST)]
    done = subprocess.run([sys.executable, "-m", "planner.cli", "generate", "sphere", "--hand", "panda", "--db",
                           str(tmp_path / "s.db"), "--quiet", "--json", *args], capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["force_closure"] >= 0


def write_obj(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


@pytest.mark.parametrize("name, content, needle", [
    ("missing.obj", None, "file not found"),
    ("empty.obj", "", "empty"),
    ("nan.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\nf 1 4 2\nf 2 4 3\n", "NaN"),
    ("inf.obj", "v 0 0 0\nv inf 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\nf 1 4 2\nf 2 4 3\n", "NaN or infinite"),
    ("flat.obj", "v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nv 0.1 0.1 0\nf 1 2 3\nf 2 4 3\n", "volume"),
])
def test_broken_mesh_files_one_line_and_db_untouched(box_db: Path, tmp_path: Path, name: str, content: str | None,
                                                     needle: str) -> None:
    path = tmp_path / name
    if content is not None:
        write_obj(path, content)
    before = snapshot(box_db)
    code, _, err = grasp("generate", str(path), "--hand", "panda", "--db", str(box_db), *FAST, "--quiet")
    one_line_error(code, err, 2, name, needle)
    assert snapshot(box_db) == before


def test_flat_mesh_refused_without_a_numpy_warning(tmp_path: Path) -> None:
    path = write_obj(tmp_path / "flat.obj", "v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nv 0.1 0.1 0\nf 1 2 3\nf 2 4 3\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a RuntimeWarning would become an internal error (exit 1)
        code, out, err = grasp("generate", str(path), "--hand", "panda", "--db", str(tmp_path / "g.db"), *FAST)
    one_line_error(code, err, 2, "flat.obj", "encloses no volume")
    assert out == ""


def test_millimetres_passed_as_metres(tmp_path: Path) -> None:
    path = tmp_path / "mm.stl"
    trimesh.creation.box(extents=[50.0, 40.0, 80.0]).export(path)
    code, _, err = grasp("generate", str(path), "--hand", "panda", "--db", str(tmp_path / "x.db"), *FAST, "--quiet")
    one_line_error(code, err, 2, "millimetres", "--scale 0.001")
    assert not (tmp_path / "x.db").exists()
    code, _, err = grasp("generate", str(path), "--scale", "0.001", "--hand", "panda", "--db", str(tmp_path / "x.db"),
                    *FAST, "--quiet")
    assert code == 0, err


def test_an_object_that_fails_among_others_is_said_once_whole(tmp_path: Path) -> None:
    """The summary table printed a failed object's error in its narrow last column, one word a line (20 lines
    for a 0.13 mm object in an 80-column terminal), and then again whole on stderr: now 'yes' in the table."""
    tiny = tmp_path / "tiny.stl"
    trimesh.creation.box(extents=[5e-4, 5e-4, 5e-4]).export(tiny)
    code, out, err = grasp("generate", str(tiny), "box", "--hand", "panda", "--db", str(tmp_path / "x.db"), *FAST)
    row = next(line for line in out.splitlines() if line.startswith("│ tiny"))
    assert code == 2 and row.split("│")[-2].strip() == "yes" and "millimetre" not in out, out
    heading = next(line for line in out.splitlines() if line.startswith("┃ object"))  # not cut to 80 columns in a log
    assert [c.strip() for c in heading.strip("┃").split("┃")] == ["object", "mass kg", "friction", "up", "units",
                                                                   "candidates", "grasps", "force-closure",
                                                                   "worker s", "error"], out
    one_line_error(code, err, 2, "tiny", "smaller than a millimetre")


def test_smaller_than_a_millimetre(tmp_path: Path) -> None:
    path = tmp_path / "tiny.stl"
    trimesh.creation.box(extents=[5e-4, 5e-4, 5e-4]).export(path)
    code, _, err = grasp("generate", str(path), "--hand", "panda", "--db", str(tmp_path / "x.db"), *FAST, "--quiet")
    one_line_error(code, err, 2, "smaller than a millimetre")


def test_broken_mesh_leaves_existing_database_untouched(box_db: Path, tmp_path: Path) -> None:
    db = tmp_path / "g.db"
    shutil.copy(box_db, db)  # a closed database: no write-ahead log beside it
    before = db.read_bytes()
    bad = tmp_path / "broken.obj"
    bad.write_text("v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n")
    code, _, err = grasp("generate", str(bad), "--hand", "panda", "--db", str(db), "--quiet", *FAST)
    assert code == 2 and "broken" in err
    assert db.read_bytes() == before and not Path(f"{db}-wal").exists()


def test_not_a_database_is_refused(tmp_path: Path) -> None:
    junk = tmp_path / "junk.db"
    junk.write_text("hello")
    code, _, err = grasp("generate", "box", "--hand", "panda", "--db", str(junk), *FAST, "--quiet")
    assert code == 3 and "not an SQLite database" in err
    assert junk.read_text() == "hello"


def _stored(db: Path, skip: tuple[str, ...] = ("id", "unit_id", "score", "p_hold", "p_hold_trial", "rank")
            ) -> dict[int, tuple]:
    with sqlite3.connect(db) as conn:
        cols = [r[1] for r in conn.execute("PRAGMA table_info(grasps)") if r[1] not in skip]
        return {r[0]: r[1:] for r in conn.execute(f"SELECT candidate, {', '.join(cols)} FROM grasps")}


def test_the_chunking_changes_no_grasp(tmp_path: Path, shipped_models: None) -> None:
    """The same seed gives the same grasps, every stored field to the bit,
    whatever the chunking (p_hold, made per written unit, to the last bits)."""
    args = ("random_000", "--hand", "panda", "--approaches", "48", "--rolls", "2", "--depths", "0",
            "--reach-placements", "0", "--workers", "1", "--quiet")
    whole, split = tmp_path / "whole.db", tmp_path / "split.db"
    assert grasp("generate", *args, "--db", str(whole))[0] == 0
    assert grasp("generate", *args, "--chunk", "8", "--db", str(split))[0] == 0
    a, b = _stored(whole), _stored(split)
    assert len(a) > 10 and a == b
    with sqlite3.connect(whole) as one, sqlite3.connect(split) as other:
        p = dict(one.execute("SELECT candidate, p_hold FROM grasps"))
        q = dict(other.execute("SELECT candidate, p_hold FROM grasps"))
    assert p.keys() == q.keys() and any(v is not None for v in p.values())
    assert all((p[k] is None and q[k] is None) or abs(p[k] - q[k]) < 1e-12 for k in p)


def test_running_the_same_command_again_changes_nothing(tmp_path: Path, shipped_models: None) -> None:
    """A hand's first grasps record the model that scored them, so the next
    run does not re-score them from their stored (rounded) inputs."""
    args = ("random_000", "--hand", "panda", "--approaches", "48", "--rolls", "2", "--depths", "0",
            "--reach-placements", "0", "--workers", "1", "--quiet", "--db", str(tmp_path / "g.db"))
    assert grasp("generate", *args)[0] == 0
    before = _stored(tmp_path / "g.db", ())
    assert grasp("generate", *args)[0] == 0
    assert _stored(tmp_path / "g.db", ()) == before


def test_a_resume_keeps_the_names_an_earlier_run_stored_files_under(tmp_path: Path) -> None:
    """Runs before 2026-12-05 prefixed the folders of every file of a run where two files shared a stem
    (``lab/cup``); today's run names ``cup.obj`` ``cup``: a resume finds the stored objects, sweeps nothing again."""
    for rel in ("a/part.obj", "b/part.obj", "cup.obj"):
        (tmp_path / "lab" / rel).parent.mkdir(parents=True, exist_ok=True)
        trimesh.creation.box(extents=(0.03, 0.03, 0.05)).export(tmp_path / "lab" / rel)
    db = tmp_path / "g.db"
    args = ["generate", str(tmp_path / "lab"), "--hand", "panda", "--db", str(db), "--json", *FAST]
    code, out, err = grasp(*args)
    assert code == 0, err
    with sqlite3.connect(db) as conn:  # as the earlier planner named it
        for table, column in (("objects", "name"), ("units", "object"), ("grasps", "object")):
            conn.execute(f"UPDATE {table} SET {column} = 'lab/cup' WHERE {column} = 'cup'")
    code, out, err = grasp(*args)
    assert code == 0, err
    assert json.loads(out)["units"] == 0 and json.loads(out)["skipped"] > 0
    with sqlite3.connect(db) as conn:
        assert sorted(n for (n,) in conn.execute("SELECT name FROM objects")) == ["a/part", "b/part", "lab/cup"]


def test_two_symlinks_to_one_mesh_are_two_objects_with_their_own_sidecars(tmp_path: Path) -> None:
    """A folder of links into a content store: each link named its object after the target (both 'a1b2') and
    read the target's sidecar; the second link's run then added grasps to the first link's object. Now each link
    is its own object, as a copy would be, with its own mass."""
    store = tmp_path / "store"
    store.mkdir()
    trimesh.creation.box(extents=(0.03, 0.04, 0.05)).export(store / "a1b2.obj")
    objects = tmp_path / "objects"
    objects.mkdir()
    for name, mass in (("brick", 0.3), ("block", 0.05)):
        (objects / f"{name}.obj").symlink_to(store / "a1b2.obj")
        (objects / f"{name}.toml").write_text(f"mass = {mass}\n")
    db = tmp_path / "g.db"
    for name in ("brick", "block"):
        code, _, err = grasp("generate", str(objects / f"{name}.obj"), "--hand", "panda", "--db", str(db), *FAST,
                             "--quiet")
        assert code == 0, err
    with sqlite3.connect(db) as conn:
        assert sorted(conn.execute("SELECT name, mass FROM objects")) == [("block", 0.05), ("brick", 0.3)]
        counts = dict(conn.execute("SELECT object, COUNT(*) FROM grasps GROUP BY object"))
    assert counts["block"] > 0 and counts["brick"] > 0  # their own sweeps (seeds derive from the name)


@pytest.mark.parametrize("args, code, needle", [
    (["--seed", "-1"], 2, "--seed must be an integer from 0 to"),  # every unit failed, stored as failed
    (["--seed", "99999999999999999999"], 2, "--seed must be an integer from 0 to"),  # an internal OverflowError
    (["--db", ""], 3, "is a folder, not a database file"),  # an internal ValueError
])
def test_seeds_and_database_paths_that_cannot_be_are_one_line(box_db: Path, tmp_path: Path, args: list[str],
                                                              code: int, needle: str) -> None:
    db = tmp_path / "g.db"
    shutil.copy(box_db, db)
    before = snapshot(db)
    exit_code, _, err = grasp("generate", "sphere", "--hand", "panda", "--db", str(db), *FAST, "--quiet", *args)
    one_line_error(exit_code, err, code, needle)
    assert snapshot(db) == before


def test_a_resume_with_another_chunk_is_refused_not_stored_twice(box_db: Path, tmp_path: Path) -> None:
    """--chunk cuts the same candidates into other units: a resume with another one swept the object again
    and stored every grasp twice (a helper's run: 404 duplicate poses)."""
    db = tmp_path / "g.db"
    shutil.copy(box_db, db)
    before = snapshot(db)
    code, _, err = grasp("generate", "box", "--hand", "panda", "--db", str(db), *FAST, "--quiet", "--chunk", "2")
    one_line_error(code, err, 2, "box was swept for panda with these settings but --chunk", "resume with --chunk")
    assert snapshot(db) == before
    code, _, err = grasp("generate", "box", "--hand", "panda", "--db", str(db), *FAST, "--quiet", "--seed", "3",
                         "--chunk", "2")  # another seed is another sweep: its own candidates
    assert code == 0, err


@pytest.mark.parametrize("option, value, least", [
    ("--approaches", "-3", 1), ("--rolls", "0", 1), ("--fan", "-1", 0), ("--chunk", "-1", 0),
    ("--reach-placements", "-1", 0), ("--reach-top", "-2", 0), ("--fc-budget", "-1", 0),
])
def test_a_count_out_of_range_names_its_option_and_value(tmp_path: Path, option: str, value: str,
                                                         least: int) -> None:
    """One message named five options ("chunk, reach placements, reach top, pre-grasp distance and the
    force-closure budget must be >= 0") and none of the values; now the option given and its value."""
    db = tmp_path / "g.db"
    code, _, err = grasp("generate", "box", "--hand", "panda", "--db", str(db), option, value)
    one_line_error(code, err, 2, f"{option} must be at least {least}, got {value}")
    assert not db.exists()


@pytest.mark.parametrize("args, differs", [
    (["--fc-budget", "0"], "fc_budget 0 (stored 1000)"),
    (["--reach-top", "0"], "reach_top 0 (stored 8)"),
    (["--preshapes", "wide,half"], 'preshapes ["wide", "half"] (stored ["wide"])'),
])
def test_a_run_that_tries_the_stored_candidates_again_is_refused_or_replaced(box_db: Path, tmp_path: Path,
                                                                             args: list[str], differs: str) -> None:
    """Settings that leave the candidates as they were started a second sweep: every grasp stored again with
    the same pose (best --top 4 gave one grasp four times; an export held each pose twice). Refused, naming what
    differs; --replace removes the stored sweep and its trials, and sweeps it again."""
    db = tmp_path / "g.db"
    shutil.copy(box_db, db)
    before = snapshot(db)
    code, _, err = grasp("generate", "box", "--hand", "panda", "--db", str(db), *FAST, "--quiet", *args)
    one_line_error(code, err, 2, "box was swept for panda with seed 0 and other settings (" + differs, "--replace")
    assert snapshot(db) == before
    code, _, err = grasp("validate", "--db", str(db), "--object", "box", "--hand", "panda", "--top", "2",
                         "--robust", "0")
    assert code == 0, err
    code, out, err = grasp("generate", "box", "--hand", "panda", "--db", str(db), *FAST, "--json", "--replace", *args)
    assert code == 0, err
    assert json.loads(out)["replaced"] == len(before)
    with sqlite3.connect(db) as conn:
        poses = [r[0] for r in conn.execute("SELECT pose FROM grasps")]
        assert len(poses) == len(set(poses)) > 0
        assert conn.execute("SELECT COUNT(*) FROM mujoco").fetchone()[0] == 0  # the removed grasps' trials
        assert conn.execute("SELECT COUNT(DISTINCT settings) FROM units").fetchone()[0] == 1  # this run's alone


def test_replace_removes_the_stored_sweep_only_once_the_new_one_is_whole(box_db: Path, tmp_path: Path) -> None:
    """--replace removed the stored sweep before any work: a run that then failed (a --unit-timeout, which
    crashed besides, an unreachable Ray cluster, Ctrl-C) left the object with no grasps. And it removed preshapes
    the run does not sweep again. Now the stored sweep stays until the new one is stored whole."""
    db = tmp_path / "g.db"
    shutil.copy(box_db, db)
    before = snapshot(db)
    code, _, err = grasp("generate", "box", "--hand", "panda", "--db", str(db), *FAST, "--quiet", "--fc-budget", "0",
                         "--replace", "--unit-timeout", "1e-6")  # every unit fails
    assert code != 0 and "time-out" in err
    assert snapshot(db) == before  # the stored sweep kept, nothing of the failed one
    code, out, err = grasp("generate", "box", "--hand", "panda", "--db", str(db), *FAST, "--json", "--fc-budget",
                           "0", "--replace", "--unit-timeout", "600")
    assert code == 0, err
    assert json.loads(out)["replaced"] == len(before)
    both = str(tmp_path / "both.db")
    common = ["generate", "box", "--hand", "panda", "--db", both, *FAST[:4], *FAST[6:], "--quiet"]
    code, _, err = grasp(*common, "--preshapes", "wide,half")
    assert code == 0, err
    code, _, err = grasp(*common, "--preshapes", "half", "--fc-budget", "0", "--replace")
    one_line_error(code, err, 2, "preshapes wide too: --replace would remove their grasps")


def test_preshapes_in_another_order_say_how_to_resume(tmp_path: Path) -> None:
    """The candidates are numbered in the order of --preshapes: another order is another sweep of the same
    candidates, refused with the stored order to resume with."""
    db = str(tmp_path / "g.db")
    common = ["generate", "box", "--hand", "panda", "--db", db, *FAST[:4], *FAST[6:], "--quiet"]
    code, _, err = grasp(*common, "--preshapes", "wide,half")
    assert code == 0, err
    code, _, err = grasp(*common, "--preshapes", "half,wide")
    one_line_error(code, err, 2, "with --preshapes wide,half: the same preshapes, named otherwise",
                   "resume with --preshapes wide,half")
    code, _, err = grasp(*common[:-1], "--quiet")  # all of them, named before, not now
    assert code == 2 and "resume with --preshapes wide,half" in err


def test_a_sweep_that_failed_partway_counts_and_antipodal_preshapes_are_one_set_of_candidates(tmp_path: Path) -> None:
    """A failed unit keeps the grasps it found, but only finished units were compared: a run with other settings
    then stored them again. And the antipodal sampler's candidate is a chord, an approach and a depth, whatever
    preshape opens the hand on it: --preshapes half after --preshapes wide stored 110 of 111 poses twice."""
    db = str(tmp_path / "g.db")
    common = ["generate", "box", "--hand", "panda", "--db", db, "--approaches", "6", "--rolls", "2", "--workers",
              "1", "--reach-placements", "1", "--quiet"]
    code, _, err = grasp(*common, "--preshapes", "wide", "--unit-timeout", "1e-6")
    assert code != 0 and "time-out" in err
    code, _, err = grasp(*common, "--preshapes", "wide", "--fc-budget", "0")
    one_line_error(code, err, 2, "fc_budget 0 (stored 1000)")
    code, _, err = grasp(*common, "--preshapes", "wide")  # the failed sweep itself: retried
    assert code == 0, err
    code, _, err = grasp(*common, "--preshapes", "half")
    one_line_error(code, err, 2, 'preshapes ["half"] (stored ["wide"])')


def test_an_upgraded_planner_does_not_add_its_grasps_beside_the_old_ones(box_db: Path, tmp_path: Path) -> None:
    """After an upgrade (ALGORITHM_VERSION is in the settings) the same command swept every object again: 39
    grasps became 78, each pose twice with another p_hold. Refused, saying so; a sweep of other candidates (another
    seed) is added."""
    db = tmp_path / "g.db"
    shutil.copy(box_db, db)
    with sqlite3.connect(db) as conn:
        conn.execute("UPDATE units SET settings = replace(settings, '\"algorithm\": ', '\"algorithm\": 1'), "
                     "settings_hash = 'old' || settings_hash")  # as an earlier version stored them
    code, _, err = grasp("generate", "box", "--hand", "panda", "--db", str(db), *FAST, "--quiet")
    one_line_error(code, err, 2, "the planner's algorithm version")
    code, _, err = grasp("generate", "box", "--hand", "panda", "--db", str(db), *FAST, "--quiet", "--seed", "5")
    assert code == 0, err


def test_a_weight_no_solid_has_is_noted(tmp_path: Path) -> None:
    """A 5 mm bead at the default 0.2 kg is 1.6e6 kg/m^3 (every measure and trial at that weight) without a
    word; now a note after the summary, none at a density given."""
    import trimesh

    bead = tmp_path / "bead.stl"
    trimesh.creation.box(extents=[0.005, 0.005, 0.005]).export(bead)
    code, _, err = grasp("generate", str(bead), "--hand", "panda", "--db", str(tmp_path / "a.db"), *FAST)
    assert code == 0 and "note: bead weighs 0.2 kg in its volume: 1.6e+06 kg/m^3, outside any solid's" in err, err
    assert "--scale" not in err
    code, _, err = grasp("generate", str(bead), "--hand", "panda", "--db", str(tmp_path / "b.db"), *FAST,
                         "--density", "1000")
    assert code == 0 and "note:" not in err, err
    # a mug modelled 1 unit across (as model datasets normalise them) is a 1 m mug: 0.2 kg in 0.5 m^3
    mug = tmp_path / "mug.stl"
    trimesh.creation.cylinder(radius=0.4, height=1.0).export(mug)
    code, _, err = grasp("generate", str(mug), "--hand", "panda", "--db", str(tmp_path / "c.db"), *FAST)
    assert code == 0 and "note: mug weighs 0.2 kg in its volume: 0.4" in err, err
    assert "another --db; if its mesh is not in metres (a model scaled to 1 unit across), --scale" in err


@pytest.mark.parametrize("address, raised, needles", [
    ("ray://127.0.0.1:10001", ValueError("Ray Client requires pip package `ray[client]`. If you installed the "
                                         "minimal Ray, please reinstall."), ("pip install 'ray[client]'",)),
    ("auto", ConnectionError("Could not find any running Ray instance. Please specify the one to connect to by "
                             "setting `--address` flag or `RAY_ADDRESS` environment variable."),
     ("Could not find any running Ray instance", "ray start --head", "--ray without an address")),
    ("ray://head:10001", ConnectionError("ray client connection timeout"), ("ray start --head",)),
    ("head", ValueError("Invalid address format: head"), ("Invalid address format", "HOST:6379")),
])
def test_a_ray_cluster_that_cannot_be_reached_is_one_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                          address: str, raised: Exception,
                                                          needles: tuple[str, ...]) -> None:
    """ray.init's refusals were internal errors (exit 1). Its errors are faked: no network, no cluster."""
    ray = pytest.importorskip("ray")

    def refuse(**_: object) -> None:
        raise raised

    monkeypatch.setattr(ray, "init", refuse)
    monkeypatch.setattr(ray, "is_initialized", lambda: False)
    monkeypatch.setattr("planner.run.ray_local._reachable", lambda *_: None)  # Ray's own refusals, past the probe
    code, _, err = grasp("generate", "box", "--hand", "panda", "--db", str(tmp_path / "r.db"), "--ray", address,
                         *FAST)
    one_line_error(code, err, 2, f"--ray {address}:", *needles)
    assert "internal error" not in err


@pytest.mark.parametrize("form", ["127.0.0.1:{port}", "ray://127.0.0.1:{port}", "ray://[::1]:{port}"])
def test_a_ray_address_nothing_answers_at_is_refused_at_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                             form: str) -> None:
    """`--ray 127.0.0.1:1` waited in Ray's own reconnect loop (minutes); a port nothing listens on is refused
    before ray.init is called, in one line (a real TCP refusal on this machine: a port just released)."""
    import socket

    ray = pytest.importorskip("ray")
    family = socket.AF_INET6 if "::1" in form else socket.AF_INET
    try:
        with socket.socket(family) as sock:
            sock.bind(("::1" if family == socket.AF_INET6 else "127.0.0.1", 0))
            port = sock.getsockname()[1]
    except OSError:
        pytest.skip("no IPv6 loopback here")
    called: list[object] = []
    monkeypatch.setattr(ray, "init", lambda **kw: called.append(kw))
    monkeypatch.setattr(ray, "is_initialized", lambda: False)
    address = form.format(port=port)
    code, _, err = grasp("generate", "box", "--hand", "panda", "--db", str(tmp_path / "r.db"), "--ray", address,
                         *FAST)
    one_line_error(code, err, 2, f"--ray {address}: nothing answers at", f":{port}", "ray start --head")
    assert not called


def test_the_help_and_the_readme_name_every_manifest_column() -> None:
    """The help left out the `[scale=S]` column the README documents: both now say the reader's own line."""
    from planner.specs.inputs import MANIFEST_LINE

    code, out, err = grasp("generate", "--help")
    assert code == 0, err
    assert MANIFEST_LINE in " ".join(out.split()) and "[scale=S]" in MANIFEST_LINE
    readme = (Path(__file__).parents[2] / "README.md").read_text(encoding="utf-8")
    assert MANIFEST_LINE in " ".join(readme.split())


def test_a_ray_samplers_preshapes_that_share_none_are_other_candidates(tmp_path: Path) -> None:
    """The Barrett's rays: each preshape closes from its own posture at its own standoffs, other candidates."""
    db = str(tmp_path / "g.db")
    common = ["generate", "box", "--hand", "barrett", "--db", db, "--approaches", "2", "--rolls", "1", "--workers",
              "1", "--reach-placements", "0", "--no-settle", "--quiet"]
    for preshapes in ("pinch", "wrap"):
        code, _, err = grasp(*common, "--preshapes", preshapes)
        assert code == 0, err


def test_a_stopped_replace_is_named_as_such_and_finished_by_the_next(box_db: Path, tmp_path: Path) -> None:
    """A --replace run stopped after some units leaves both sweeps; a run without --replace said 'give another
    --seed', not that the replacement was unfinished."""
    from planner import api
    from planner.errors import InputError
    from planner.plan.sweep import SweepSettings

    db = tmp_path / "g.db"
    shutil.copy(box_db, db)
    stored = len(snapshot(db))
    settings = SweepSettings(approaches=6, rolls=2, preshapes=("wide",), reach_placements=1, chunk=2, fc_budget=0)

    def stop(p: api.GenerateProgress) -> None:
        if p.result is not None:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        api.generate(["box"], "panda", db_path=db, settings=settings, replace=True, progress=stop)
    with pytest.raises(InputError, match="holds two sweeps for panda.*run it again with --replace to finish"):
        api.generate(["box"], "panda", db_path=db, settings=settings)
    assert api.generate(["box"], "panda", db_path=db, settings=settings, replace=True).replaced == stored


def test_whose_verdicts_the_report_counts_and_which_sidecar_gave_a_value(tmp_path: Path) -> None:
    from dataclasses import replace

    from planner.api.givers import from_files
    from planner.present.report import engines
    from planner.record.grasp import Trial
    from planner.specs.objects import resolve_spec
    from planner.specs.physical import NO_PHYSICAL
    from tests.helpers import made_up

    held = Trial(True, 2, 0.0, 0.0, 0.0, 0.0, "held")
    grasps = [replace(made_up(1, 0.1), mujoco=held)] * 2 + [replace(made_up(2, 0.1), validation=held)] * 3
    assert engines(grasps) == "MuJoCo 2, PyBullet 3"  # no grasp was tried by both
    assert engines([replace(made_up(1, 0.1), mujoco=held, validation=held)]).endswith("where both tried a grasp)")
    mesh = tmp_path / "S.STL"
    trimesh.creation.box(extents=[0.03, 0.03, 0.03]).export(mesh)
    mesh.with_suffix(".TOML").write_text("mass = 0.07\n")
    assert from_files(str(mesh), resolve_spec(str(mesh)), NO_PHYSICAL) == " (mass from S.TOML)"


def test_the_bars_last_line_is_whole_in_a_log(tmp_path: Path) -> None:
    """Written to a file or a pipe, Rich cut the bar to 80 columns: "generati… 256/256 candidates 2/2 uni… 67
    grasps, 67 force-closure, 48 cand/s E…" (as it cut the summary's headings)."""
    import subprocess
    import sys

    from processes import env

    done = subprocess.run([sys.executable, "-m", "planner.cli", "generate", "box", "--hand", "panda", "--db",
                           str(tmp_path / "g.db"), *FAST], env=env(), capture_output=True, text=True, timeout=300)
    bar = done.stdout.splitlines()[0]
    assert done.returncode == 0 and bar.startswith("generating ") and " units " in bar and bar.endswith(
        "ETA 0:00:00"), done.stdout


@pytest.mark.parametrize("mode", ["--quiet", "--json"])
def test_a_weight_no_solid_has_is_noted_under_quiet_and_json(tmp_path: Path, mode: str) -> None:
    """A mesh scaled x10 at the default 0.2 kg is ~1 kg/m^3: the note came with the summary table only, so
    `--quiet`, `--json` (and the Python API) ran it without a word. Said by the library, on stderr."""
    import trimesh

    box = tmp_path / "crate.stl"
    trimesh.creation.box(extents=[0.06, 0.06, 0.06]).export(box)  # x10: 0.6 m across, 0.216 m^3
    code, out, err = grasp("generate", str(box), "--hand", "panda", "--db", str(tmp_path / "a.db"), *FAST,
                           "--scale", "10", mode)
    assert code == 0 and "note: crate weighs 0.2 kg in its volume: 0.926 kg/m^3, outside any solid's" in err, err
    assert "give --mass or --density" in err and "--scale" in err and "note:" not in out
