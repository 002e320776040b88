"""``grasp generate --mass/--density/--friction``, manifest columns and
sidecars end to end: the values stored, used by the measures, exported, and
an object stored at other values refused."""

from __future__ import annotations

import csv
import json
import os
import sqlite3
from pathlib import Path

import h5py
import numpy as np
import pytest
import trimesh
from helpers import FAST, NUM_TOL, grasp, one_line_error

from planner.errors import InputError

BRICK = (0.05, 0.04, 0.06)  # [m]
VOLUME = BRICK[0] * BRICK[1] * BRICK[2]


def stored(db: Path) -> dict[str, tuple[float, float, float]]:
    with sqlite3.connect(db) as conn:
        return {n: (m, f, d) for n, m, f, d in conn.execute("SELECT name, mass, friction, density FROM objects")}


def measures(db: Path) -> dict[int, tuple[float, float]]:
    with sqlite3.connect(db) as conn:
        return {c: (w, e) for c, w, e in conn.execute(
            "SELECT candidate, resist_worst, epsilon FROM grasps WHERE resist_worst IS NOT NULL")}


@pytest.fixture
def brick(tmp_path: Path) -> Path:
    path = tmp_path / "meshes" / "brick.obj"
    path.parent.mkdir()
    trimesh.creation.box(extents=BRICK).export(path)
    return path


def generate(db: Path, *args: str) -> tuple[int, str, str]:
    return grasp("generate", *args, "--hand", "panda", "--db", str(db), "--quiet", *FAST)


def test_flags_are_stored_and_used_by_the_measures(tmp_path: Path) -> None:
    light, heavy = tmp_path / "light.db", tmp_path / "heavy.db"
    assert generate(light, "box", "--mass", "0.1", "--friction", "0.5")[0] == 0
    assert generate(heavy, "box", "--mass", "0.4", "--friction", "0.5")[0] == 0
    assert stored(light)["box"][:2] == (0.1, 0.5) and stored(heavy)["box"][:2] == (0.4, 0.5)
    a, b = measures(light), measures(heavy)
    assert a.keys() == b.keys() and a
    for candidate in a:  # epsilon is the shape's; the weight the grasp resists grows with the mass
        assert a[candidate][1] == pytest.approx(b[candidate][1], abs=NUM_TOL)
        assert a[candidate][0] > b[candidate][0]


def test_density_flag_stores_the_mass_it_gives(tmp_path: Path, brick: Path) -> None:
    db = tmp_path / "g.db"
    code, _, err = generate(db, str(brick), "--density", "500")
    assert code == 0, err
    mass, friction, density = stored(db)["brick"]
    assert density == 500.0 and mass == pytest.approx(500.0 * VOLUME, rel=NUM_TOL) and friction == 0.5


def test_sidecar_and_manifest_values_are_stored(tmp_path: Path, brick: Path) -> None:
    brick.with_suffix(".toml").write_text("mass = 0.066\nfriction = 0.8\n")
    other = brick.with_name("slab.obj")
    trimesh.creation.box(extents=(0.06, 0.05, 0.03)).export(other)
    (tmp_path / "list.txt").write_text("meshes/brick.obj\nmeshes/slab.obj density=300 friction=0.6\n")
    db = tmp_path / "g.db"
    code, _, err = generate(db, f"@{tmp_path / 'list.txt'}", "--friction", "0.4")
    assert code == 0, err
    rows = stored(db)
    assert rows["brick"][:2] == (0.066, 0.4)  # the sidecar's mass; the run's friction beats the sidecar's
    assert rows["slab"][1:] == (0.6, 300.0)


@pytest.mark.parametrize("args, needle", [
    (["--mass", "-1"], "--mass must be a positive number [kg], got -1"),
    (["--mass", "0"], "--mass must be a positive number"),
    (["--density", "nan"], "--density must be a positive number"),
    (["--friction", "0"], "--friction must be a positive number"),
    (["--friction", "4"], "--friction must lie in (0, 3]"),
    (["--mass", "abc"], "Invalid value for '--mass'"),
    (["--mass", "0.2", "--density", "300"], "--mass and --density exclude each other"),
    (["--up", "w"], "--up must be an axis of the object's file, one of +x -x +y -y +z -z"),
    (["--up", "+yz"], "--up must be an axis"),
])
def test_bad_flags_are_one_line_before_any_database(tmp_path: Path, args: list[str], needle: str) -> None:
    db = tmp_path / "g.db"
    code, out, err = generate(db, "box", *args)
    one_line_error(code, err, 2, needle)
    assert not db.exists() and out == ""


def test_bad_sidecar_is_one_line(tmp_path: Path, brick: Path) -> None:
    brick.with_suffix(".toml").write_text('friction = "high"\n')
    code, _, err = generate(tmp_path / "g.db", str(brick))
    one_line_error(code, err, 2, "brick.toml: friction must be a number")


def test_another_mass_does_not_mix_with_stored_grasps(tmp_path: Path, brick: Path) -> None:
    db = tmp_path / "g.db"
    assert generate(db, str(brick), "--mass", "0.1")[0] == 0
    with sqlite3.connect(db) as conn:
        before = conn.execute("SELECT COUNT(*) FROM grasps").fetchone()
    code, _, err = generate(db, str(brick), "--mass", "0.3")
    one_line_error(code, err, 2, "object 'brick' is stored", "with mass 0.1", "this run gives mass 0.3")
    code, _, err = grasp("generate", str(brick), "--hand", "barrett", "--db", str(db), "--quiet", *FAST[:4],
                         "--friction", "0.9")  # another hand shares the object's row: refused as well
    one_line_error(code, err, 2, "friction 0.5", "friction 0.9")
    with sqlite3.connect(db) as conn:
        assert conn.execute("SELECT COUNT(*) FROM grasps").fetchone() == before
    assert stored(db)["brick"][0] == 0.1
    assert generate(db, str(brick), "--mass", "0.1")[0] == 0  # the same values resume


def test_exports_carry_mass_friction_and_density(tmp_path: Path, brick: Path) -> None:
    db = tmp_path / "g.db"
    assert generate(db, str(brick), "--density", "400", "--friction", "0.7")[0] == 0
    mass = 400.0 * VOLUME
    for fmt in ("acronym", "graspgen", "csv"):
        code, _, err = grasp("export", "--db", str(db), "--format", fmt, "--out", str(tmp_path / fmt))
        assert code == 0, err
    with h5py.File(tmp_path / "acronym" / "brick__panda.h5") as f:
        got = [float(f[f"object/{k}"][()]) for k in ("mass", "friction", "density")]
    assert np.allclose(got, [mass, 0.7, 400.0], rtol=NUM_TOL)
    data = json.loads((tmp_path / "graspgen" / "grasp_data" / "panda" / "brick.json").read_text())
    assert np.allclose([data["object"][k] for k in ("mass", "friction", "density")], [mass, 0.7, 400.0], rtol=NUM_TOL)
    table = next((tmp_path / "csv").rglob("*.csv"))
    with table.open() as fh:
        row = next(csv.DictReader(fh))
    assert np.allclose([float(row[k]) for k in ("object_mass", "object_friction", "object_density")],
                       [mass, 0.7, 400.0], rtol=NUM_TOL)


def test_worker_processes_plan_at_the_given_values(tmp_path: Path) -> None:
    """The values travel with each unit to the pool's workers (the stored row is the worker's object)."""
    one, two = tmp_path / "one.db", tmp_path / "two.db"
    assert generate(one, "box", "--mass", "0.3", "--friction", "0.6")[0] == 0
    code, _, err = generate(two, "box", "--mass", "0.3", "--friction", "0.6", "--workers", "2", "--chunk", "3")
    assert code == 0, err
    assert stored(two)["box"][:2] == (0.3, 0.6)
    assert measures(two) == measures(one)


def _file_bytes(db: Path) -> bytes:
    with sqlite3.connect(db) as conn:
        conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    return db.read_bytes()


@pytest.mark.parametrize("change", ["scale", "other_file", "edited", "edited_finished"])
def test_another_mesh_under_a_stored_name_is_refused(tmp_path: Path, brick: Path, change: str) -> None:
    """One name, one mesh: another --scale, another file of the same name or
    the file edited since are refused before anything is written (their
    grasps would be ranked and exported with the stored ones)."""
    db = tmp_path / "g.db"
    assert generate(db, str(brick))[0] == 0
    before = _file_bytes(db)
    source, extra = str(brick), []
    if change == "scale":
        extra = ["--scale", "0.5"]
    elif change == "other_file":
        other = tmp_path / "elsewhere" / "brick.obj"
        other.parent.mkdir()
        trimesh.creation.box(extents=(0.03, 0.03, 0.05)).export(other)
        source = str(other)
    else:  # edited in place: units to run (another seed), or the same finished sweep again
        trimesh.creation.box(extents=(0.05, 0.04, 0.07)).export(brick)
        extra = ["--seed", "1"] if change == "edited" else []
    code, _, err = generate(db, source, *extra)
    one_line_error(code, err, 2, "object 'brick' is stored", "from another mesh", "use another --db")
    assert _file_bytes(db) == before
    code, _, err = grasp("best", "brick", "--hand", "panda", "--db", str(db))
    assert code == 0
    assert ("was modified (its modification time) after brick" in err) == change.startswith("edited"), err


def test_a_finished_sweep_of_an_unchanged_file_is_skipped(tmp_path: Path, brick: Path) -> None:
    """The same command again on a file untouched since its sweep finished skips every unit (the mesh is not
    compared), also when the file was last modified long before."""
    db = tmp_path / "g.db"
    os.utime(brick, (1e9, 1e9))  # 2001
    assert generate(db, str(brick))[0] == 0
    code, out, err = grasp("generate", str(brick), "--hand", "panda", "--db", str(db), "--json", *FAST)
    assert code == 0, err
    assert json.loads(out)["skipped"] > 0 and json.loads(out)["units"] == 0


def test_the_store_refuses_a_unit_of_another_mesh(tmp_path: Path) -> None:
    """The store's own guard, beneath generate's check: a unit whose object
    has another mesh than the stored one of its name writes nothing."""
    from dataclasses import replace

    from planner.db.rows import UnitRow
    from planner.db.store import open_db
    from planner.geometry.solid import load_object

    db = tmp_path / "g.db"
    assert generate(db, "box")[0] == 0
    before = _file_bytes(db)
    other = replace(load_object("box"), mesh_hash="0" * 64)
    with open_db(db) as store:
        with pytest.raises(InputError, match="from another mesh than this unit's"):
            store.write_unit(UnitRow("box", "panda", "x", "{}", 0, 99), other, [], store.rule())
    assert _file_bytes(db) == before


def test_generate_and_db_objects_say_the_values_used(tmp_path: Path, brick: Path) -> None:
    brick.with_suffix(".toml").write_text("mass = 0.066\nfriction = 0.8\n")
    db = tmp_path / "g.db"
    code, out, err = grasp("generate", str(brick), "box", "--hand", "panda", "--db", str(db), "--json", *FAST)
    assert code == 0, err
    rows = {r["object"]: r for r in json.loads(out)["objects"]}
    assert (rows["brick"]["mass"], rows["brick"]["friction"]) == (0.066, 0.8)  # the sidecar's
    assert (rows["box"]["mass"], rows["box"]["friction"]) == (stored(db)["box"][0], stored(db)["box"][1])
    code, out, err = grasp("db", "objects", "--db", str(db))
    assert code == 0, err
    lines = {line.split(":")[0]: line for line in out.splitlines()}
    assert set(lines) == {"box", "brick"}
    assert "mass 0.066 kg" in lines["brick"] and "friction 0.8" in lines["brick"] and str(brick) in lines["brick"]
    assert f"density {0.066 / VOLUME:.4g} kg/m^3" in lines["brick"] and "grasps for panda" in lines["brick"]


def test_the_same_mesh_from_another_folder_resumes(tmp_path: Path, brick: Path) -> None:
    """A stored object whose file moved (the same bytes elsewhere) is the
    same object: its finished units are skipped, new ones run."""
    db = tmp_path / "g.db"
    assert generate(db, str(brick))[0] == 0
    moved = tmp_path / "moved" / "brick.obj"
    moved.parent.mkdir()
    moved.write_bytes(brick.read_bytes())
    code, out, err = grasp("generate", str(moved), "--hand", "panda", "--db", str(db), "--json", *FAST)
    assert code == 0, err
    assert json.loads(out)["skipped"] >= 1
    assert generate(db, str(moved), "--seed", "1")[0] == 0  # new units of the same object


def test_mass_properties_of_an_earlier_planner_are_not_mixed(tmp_path: Path, brick: Path) -> None:
    """A row whose volume this planner does not give the same mesh (an
    earlier planner's, e.g. overlapping bodies counted twice): new units
    are refused; finished ones are still skipped."""
    db = tmp_path / "g.db"
    assert generate(db, str(brick))[0] == 0
    with sqlite3.connect(db) as conn:
        conn.execute("UPDATE objects SET volume = volume * 1.3 WHERE name = 'brick'")
    assert generate(db, str(brick))[0] == 0  # nothing to run
    code, _, err = generate(db, str(brick), "--seed", "1")
    one_line_error(code, err, 2, "object 'brick' is stored", "with a volume of", "use another --db")


def test_a_refusal_says_when_the_sidecar_gave_the_value(tmp_path: Path, brick: Path) -> None:
    db = tmp_path / "g.db"
    brick.with_suffix(".toml").write_text("mass = 0.066\n")
    assert generate(db, str(brick))[0] == 0
    brick.with_suffix(".toml").write_text("mass = 0.1\nfriction = 0.7\n")
    code, _, err = generate(db, str(brick))
    one_line_error(code, err, 2, "with mass 0.066, friction 0.5", "this run gives mass 0.1, friction 0.7 "
                   "(mass and friction from brick.toml)")
    code, _, err = generate(db, str(brick), "--mass", "0.2", "--friction", "0.5")  # the flags win: no sidecar named
    one_line_error(code, err, 2, "this run gives mass 0.2, friction 0.5;")


def test_an_edit_is_seen_in_another_time_zone(tmp_path: Path, brick: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """units.finished_at carries its offset: a database swept in UTC and read west of it still sees the file
    edited after the sweep (as local wall-clock text it read 8 hours late there)."""
    import time

    db = tmp_path / "g.db"
    monkeypatch.setenv("TZ", "UTC")
    time.tzset()
    try:
        assert generate(db, str(brick))[0] == 0
        trimesh.creation.box(extents=(0.05, 0.04, 0.07)).export(brick)
        monkeypatch.setenv("TZ", "America/Los_Angeles")
        time.tzset()
        code, _, err = grasp("best", "brick", "--hand", "panda", "--db", str(db))
        assert code == 0 and "was modified (its modification time) after brick" in err, err
        code, _, err = generate(db, str(brick))
        one_line_error(code, err, 2, "object 'brick' is stored", "from another mesh")
    finally:
        monkeypatch.delenv("TZ")
        time.tzset()


def test_a_flag_replacing_a_sidecars_value_is_said(tmp_path: Path, brick: Path) -> None:
    """--mass with a sidecar giving a mass: the flag wins (as documented), without a word that the sidecar's
    mass was set aside."""
    brick.with_suffix(".toml").write_text("mass = 0.066\nfriction = 0.8\n")
    db = tmp_path / "g.db"
    code, _, err = grasp("generate", str(brick), "--hand", "panda", "--db", str(db), "--mass", "0.3", *FAST)
    assert code == 0, err
    assert "object 'brick': mass 0.3 as given replaces brick.toml's mass 0.066" in err
    assert stored(db)["brick"][:2] == (0.3, 0.8)  # the sidecar's friction, which no flag replaced
    code, _, err = grasp("generate", str(brick), "--hand", "panda", "--db", str(tmp_path / "h.db"), "--friction",
                         "0.9", "--density", "500", *FAST)
    assert code == 0, err
    assert "object 'brick': density 500, friction 0.9 as given replace brick.toml's mass 0.066, friction 0.8" in err


def test_db_objects_says_a_centred_object_is_at_0_not_minus_0(tmp_path: Path) -> None:
    """The cylinder's centre of mass read "(-0, 0, -0) mm"."""
    db = tmp_path / "g.db"
    code, _, err = grasp("generate", "cylinder", "--hand", "panda", "--db", str(db), "--quiet", *FAST)
    assert code == 0, err
    code, out, err = grasp("db", "objects", "--db", str(db))
    assert code == 0 and "centre of mass (0, 0, 0) mm" in out, out + err
