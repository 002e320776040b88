"""``grasp generate --up``, a sidecar's ``up`` and a manifest's ``up=`` end to end: stored with the object, an
object stored with another up refused, a bad value one line before any database, shown by ``db objects`` and
``best``, carried by the exports and read back by ``import``."""

from __future__ import annotations

import csv
import json
import sqlite3
from pathlib import Path

import h5py
import pytest
import trimesh
from helpers import FAST, grasp, one_line_error

from planner.errors import InputError


def stored_up(db: Path) -> dict[str, str]:
    with sqlite3.connect(db) as conn:
        return dict(conn.execute("SELECT name, up FROM objects"))


@pytest.fixture
def brick(tmp_path: Path) -> Path:
    path = tmp_path / "meshes" / "brick.obj"
    path.parent.mkdir()
    trimesh.creation.box(extents=(0.05, 0.04, 0.06)).export(path)
    return path


def generate(db: Path, *args: str) -> tuple[int, str, str]:
    return grasp("generate", *args, "--hand", "panda", "--db", str(db), "--quiet", *FAST)


def test_the_flag_the_sidecar_and_the_manifest_give_the_stored_up(tmp_path: Path, brick: Path) -> None:
    slab, cup = brick.with_name("slab.obj"), brick.with_name("cup.glb")
    trimesh.creation.box(extents=(0.06, 0.05, 0.03)).export(slab)
    trimesh.creation.box(extents=(0.04, 0.06, 0.04)).export(cup)
    slab.with_suffix(".toml").write_text('up = "-x"\n')
    (tmp_path / "list.txt").write_text("meshes/brick.obj up=y\nmeshes/slab.obj\nmeshes/cup.glb\n")
    db = tmp_path / "g.db"
    code, _, err = generate(db, f"@{tmp_path / 'list.txt'}", "box")
    assert code == 0, err
    assert stored_up(db) == {"brick": "+y", "slab": "-x", "cup": "+y", "box": "+z"}  # a glb is Y-up unless told
    flagged = tmp_path / "flag.db"
    assert generate(flagged, str(cup), "--up", "+z")[0] == 0
    assert stored_up(flagged) == {"cup": "+z"}


def test_a_bad_up_in_a_sidecar_or_manifest_names_where(tmp_path: Path, brick: Path) -> None:
    brick.with_suffix(".toml").write_text('up = "north"\n')
    code, _, err = generate(tmp_path / "g.db", str(brick))
    one_line_error(code, err, 2, "brick.toml: up must be an axis", "'north'")
    brick.with_suffix(".toml").unlink()
    (tmp_path / "list.txt").write_text("meshes/brick.obj up=0,1,0\n")
    code, _, err = generate(tmp_path / "g.db", f"@{tmp_path / 'list.txt'}")
    one_line_error(code, err, 2, "list.txt:1: up must be an axis")
    assert not (tmp_path / "g.db").exists()


def test_an_object_stored_with_another_up_is_refused(tmp_path: Path, brick: Path) -> None:
    db = tmp_path / "g.db"
    assert generate(db, str(brick), "--up", "+y")[0] == 0
    with sqlite3.connect(db) as conn:
        before = conn.execute("SELECT COUNT(*) FROM grasps").fetchone()
    code, _, err = generate(db, str(brick))
    one_line_error(code, err, 2, "object 'brick' is stored", "up +y", "this run gives", "up +z",
                   "give --up +y to go on with it")
    with sqlite3.connect(db) as conn:
        assert conn.execute("SELECT COUNT(*) FROM grasps").fetchone() == before
    assert generate(db, str(brick), "--up", "y")[0] == 0  # the same up resumes


def test_an_up_a_manifest_line_gives_is_told_to_change_there(tmp_path: Path, brick: Path) -> None:
    """A manifest line's up= wins over --up: the refusal points at the line, whose up= then goes on."""
    db = tmp_path / "g.db"
    assert generate(db, str(brick))[0] == 0
    listed = tmp_path / "list.txt"
    listed.write_text("meshes/brick.obj up=+y\n")
    code, _, err = generate(db, f"@{listed}", "--up", "+z")
    one_line_error(code, err, 2, "up +y", "give up=+z on its manifest line to go on with it")
    assert "--up +z" not in err
    listed.write_text("meshes/brick.obj up=+z\n")
    assert generate(db, f"@{listed}", "--up", "+x")[0] == 0


def test_the_store_refuses_a_unit_of_another_up(tmp_path: Path) -> None:
    from dataclasses import replace

    from planner.db.rows import UnitRow
    from planner.db.store import open_db
    from planner.geometry.solid import load_object

    db = tmp_path / "g.db"
    assert generate(db, "box")[0] == 0
    box = load_object("box")
    with open_db(db) as store:
        with pytest.raises(InputError, match=r"with up \+z, this unit's is \+y"):
            store.write_unit(UnitRow("box", "panda", "x", "{}", 0, 99), replace(box, spec=replace(box.spec, up="+y")),
                             [], store.rule())
        assert store.object_row("box").up == "+z"  # type: ignore[union-attr]


def test_generate_db_objects_and_best_say_the_up(tmp_path: Path, brick: Path) -> None:
    db = tmp_path / "g.db"
    code, out, err = grasp("generate", str(brick), "--up", "-y", "--hand", "panda", "--db", str(db), "--json", *FAST)
    assert code == 0, err
    assert json.loads(out)["objects"][0]["up"] == "-y"
    code, out, _ = grasp("db", "objects", "--db", str(db))
    assert code == 0 and "up -y" in out
    code, out, _ = grasp("best", "brick", "--hand", "panda", "--db", str(db))
    assert code == 0 and "the object's up is its frame's -y" in out
    code, out, _ = grasp("best", "brick", "--hand", "panda", "--db", str(db), "--json")
    assert code == 0 and json.loads(out)[0]["object_up"] == "-y"


def test_exports_carry_the_up_and_an_import_reads_it_back(tmp_path: Path, brick: Path) -> None:
    db = tmp_path / "g.db"
    assert generate(db, str(brick), "--up", "+x")[0] == 0
    for fmt in ("acronym", "graspgen", "csv", "parquet"):
        code, _, err = grasp("export", "--db", str(db), "--format", fmt, "--out", str(tmp_path / fmt), "--quiet")
        assert code == 0, err
    h5 = tmp_path / "acronym" / "brick__panda.h5"
    with h5py.File(h5) as f:
        assert f["object/up"][()].decode() == "+x"
    data = json.loads((tmp_path / "graspgen" / "grasp_data" / "panda" / "brick.json").read_text())
    assert data["object"]["up"] == "+x"
    with next((tmp_path / "csv").rglob("*.csv")).open() as fh:
        assert {row["object_up"] for row in csv.DictReader(fh)} == {"+x"}
    import pyarrow.parquet as pq

    assert set(pq.read_table(tmp_path / "parquet" / "grasps.parquet").column("object_up").to_pylist()) == {"+x"}
    fresh = tmp_path / "fresh.db"  # the exported mesh is an OBJ (+z unless told): the file's object/up restores it
    code, _, err = grasp("import", str(h5), "--db", str(fresh))
    assert code == 0, err
    assert stored_up(fresh) == {"brick": "+x"}


def test_import_up_applies_where_a_file_gives_none_and_refuses_another_than_the_files(tmp_path: Path,
                                                                                       brick: Path) -> None:
    db = tmp_path / "g.db"
    assert generate(db, str(brick))[0] == 0
    code, _, err = grasp("export", "--db", str(db), "--format", "acronym", "--out", str(tmp_path / "out"), "--quiet")
    assert code == 0, err
    h5 = tmp_path / "out" / "brick__panda.h5"
    code, _, err = grasp("import", str(h5), "--db", str(tmp_path / "a.db"), "--up", "+y")
    one_line_error(code, err, 2, "its object/up is +z, and --up gives +y")  # measured about +z: not another
    assert not (tmp_path / "a.db").exists()
    code, _, err = grasp("import", str(h5), "--db", str(tmp_path / "a.db"), "--up", "north")
    one_line_error(code, err, 2, "--up must be an axis")
    foreign = tmp_path / "out" / "foreign.h5"  # a file as ACRONYM's own: no object/up, no qualities of ours
    with h5py.File(h5) as src, h5py.File(foreign, "w") as f:
        for key in ("gripper/type", "gripper/configuration", "object/file", "object/scale", "object/mass",
                    "object/friction"):
            f[key] = src[key][()]
        f["grasps/transforms"] = src["grasps/transforms"][:4]
    code, _, err = grasp("import", str(foreign), "--db", str(tmp_path / "y.db"), "--up", "y", "--workers", "1")
    assert code == 0, err
    assert set(stored_up(tmp_path / "y.db").values()) == {"+y"}
    code, _, err = grasp("import", str(foreign), "--db", str(tmp_path / "z.db"), "--workers", "1")
    assert code == 0, err
    assert set(stored_up(tmp_path / "z.db").values()) == {"+z"}  # its OBJ mesh's default
