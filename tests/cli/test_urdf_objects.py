"""``grasp generate obj.urdf`` end to end: the object the URDF places, with its
mass and friction, stored and exported as the URDF says; resumed and refused as
a mesh file is; bad URDFs refused in one line before anything is written."""

from __future__ import annotations

import os
import sqlite3
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
import trimesh
from helpers import FAST, grasp, one_line_error

from planner.geometry.mesh import load_mesh_file

BRICK = (0.03, 0.05, 0.07)  # [m] the mesh file's extents
#: Where the URDF puts it: half size, a quarter turn about z (x and y swap), 2 cm up.
PLACED = [[-0.0125, -0.0075, 0.0025], [0.0125, 0.0075, 0.0375]]
#: [m] an exported OBJ keeps 8 digits or so.
EXPORT_TOL = 1e-6


def write_urdf(folder: Path, mass: str = "0.25", friction: str = "0.9", scale: str = "0.5") -> Path:
    (folder / "meshes").mkdir(parents=True, exist_ok=True)
    trimesh.creation.box(extents=BRICK).export(folder / "meshes" / "brick.obj")
    urdf = folder / "brick.urdf"
    urdf.write_text(f"""<robot name="brick"><link name="base">
  <contact><lateral_friction value="{friction}"/></contact>
  <inertial><origin xyz="0 0 0.02"/><mass value="{mass}"/></inertial>
  <collision><origin xyz="0 0 0.02" rpy="0 0 1.5707963267948966"/>
    <geometry><mesh filename="meshes/brick.obj" scale="{scale}"/></geometry></collision>
</link></robot>""")
    return urdf


def generate(db: Path, *args: str) -> tuple[int, str, str]:
    return grasp("generate", *args, "--hand", "panda", "--db", str(db), "--quiet", *FAST)


def stored(db: Path) -> tuple:
    with sqlite3.connect(db) as conn:
        return conn.execute("SELECT name, source, scale, mass, friction, density FROM objects").fetchone()


def test_a_urdf_is_planned_stored_and_exported_as_it_says(tmp_path: Path) -> None:
    urdf = write_urdf(tmp_path)
    db = tmp_path / "g.db"
    code, _, err = generate(db, str(urdf))
    assert code == 0, err
    name, source, scale, mass, friction, density = stored(db)
    assert (name, source, scale, mass, friction) == ("brick", str(urdf), 1.0, 0.25, 0.9)
    assert density == pytest.approx(0.25 / np.prod(np.array(BRICK) / 2), rel=1e-9)  # the mass over the placed volume
    code, _, err = grasp("export", "--db", str(db), "--format", "acronym", "--out", str(tmp_path / "out"))
    assert code == 0, err
    with h5py.File(tmp_path / "out" / "brick__panda.h5") as f:
        assert (float(f["object/mass"][()]), float(f["object/friction"][()])) == (0.25, 0.9)
        assert f["object/source"][()].decode() == str(urdf)
        exported = load_mesh_file(tmp_path / "out" / f["object/file"][()].decode(), float(f["object/scale"][()]))
    assert np.allclose(exported.bounds, PLACED, atol=EXPORT_TOL), exported.bounds
    code, out, err = grasp("generate", str(urdf), "--hand", "panda", "--db", str(db), "--json", *FAST)
    assert code == 0 and '"skipped": 1' in out, err
    for command in (("best", str(urdf)), ("best", "brick"), ("show", str(urdf), "--out", str(tmp_path / "g.png"))):
        code, _, err = grasp(*command, "--hand", "panda", "--db", str(db))
        assert code == 0, err
    code, out, err = grasp("validate", "--db", str(db), "--object", "brick", "--hand", "panda", "--top", "3")
    assert code == 0 and "validated 3 grasps" in out, (out, err)


@pytest.mark.parametrize("edited", ["urdf", "mesh"])
def test_an_edit_of_the_urdf_or_its_mesh_is_seen(tmp_path: Path, edited: str) -> None:
    """The URDF's mass changed, or its mesh: the stored grasps are of the object as it was."""
    urdf = write_urdf(tmp_path)
    db = tmp_path / "g.db"
    assert generate(db, str(urdf))[0] == 0
    later = time.time() + 5
    if edited == "urdf":
        write_urdf(tmp_path, mass="0.4")
        code, _, err = generate(db, str(urdf))
        one_line_error(code, err, 2, "object 'brick' is stored", "with mass 0.25, friction 0.9",
                       "this run gives mass 0.4, friction 0.9 (mass, friction and com from brick.urdf)")
    else:
        mesh = tmp_path / "meshes" / "brick.obj"
        trimesh.creation.box(extents=(0.03, 0.05, 0.08)).export(mesh)
        os.utime(mesh, (later, later))
        code, _, err = grasp("best", "brick", "--hand", "panda", "--db", str(db))
        assert code == 0 and "was modified (its modification time) after brick" in err, err
        code, _, err = generate(db, str(urdf))
        one_line_error(code, err, 2, "object 'brick' is stored", "from another mesh")


def test_a_flag_replacing_the_urdfs_value_is_said(tmp_path: Path) -> None:
    urdf = write_urdf(tmp_path)
    urdf.with_suffix(".toml").write_text("friction = 0.7\n")
    db = tmp_path / "g.db"
    code, _, err = grasp("generate", str(urdf), "--hand", "panda", "--db", str(db), "--mass", "0.3", *FAST)
    assert code == 0, err
    assert "object 'brick': mass 0.3 as given replaces brick.urdf's mass 0.25" in err
    assert "object 'brick': friction 0.7 from brick.toml replaces brick.urdf's friction 0.9" in err
    assert stored(db)[3:5] == (0.3, 0.7)


def test_a_value_given_equal_to_the_urdfs_is_not_said_to_replace_it(tmp_path: Path) -> None:
    urdf = write_urdf(tmp_path)
    code, _, err = grasp("generate", str(urdf), "--hand", "panda", "--db", str(tmp_path / "g.db"), "--friction", "0.9",
                         "--mass", "0.3", *FAST)
    assert code == 0, err
    assert "mass 0.3 as given replaces brick.urdf's mass 0.25" in err
    assert "friction" not in err.split("replaces")[-1]  # 0.9 for 0.9: nothing replaced, nothing said


def test_a_urdf_is_z_up_unless_its_sidecar_or_a_flag_says_otherwise(tmp_path: Path) -> None:
    urdf = write_urdf(tmp_path)
    db = tmp_path / "g.db"
    code, _, err = generate(db, str(urdf))
    assert code == 0, err
    with sqlite3.connect(db) as conn:
        assert conn.execute("SELECT up FROM objects").fetchone() == ("+z",)  # a URDF's frame: Z-up, as PyBullet's
    urdf.with_suffix(".toml").write_text('up = "+y"\n')
    db2 = tmp_path / "g2.db"
    code, _, err = grasp("generate", str(urdf), "--hand", "panda", "--db", str(db2), "--up", "-x", *FAST)
    assert code == 0, err
    assert "object 'brick': up -x as given replaces brick.toml's up +y" in err
    with sqlite3.connect(db2) as conn:
        assert conn.execute("SELECT up FROM objects").fetchone() == ("-x",)


@pytest.mark.parametrize("change, needle", [
    (lambda u: u.write_text(u.read_text().replace("</robot>", "")), "malformed URDF"),
    (lambda u: (u.parent / "meshes" / "brick.obj").unlink(), "mesh file not found: meshes/brick.obj"),
    (lambda u: u.write_text(u.read_text().replace('value="0.25"', 'value="0"')), "mass must be a positive number"),
    (lambda u: u.write_text(u.read_text().replace('value="0.25"', 'value="-2"')), "got -2.0"),
    (lambda u: u.write_text(u.read_text().replace('value="0.9"', 'value="4"')), "friction must lie in (0, 3]"),
    (lambda u: u.write_text(u.read_text().replace("brick.obj", "brick.dae")), "unsupported mesh type '.dae'"),
    (lambda u: u.write_text(u.read_text().replace("</link>", '</link><link name="lid"><collision><geometry><box '
                                                  'size="0.01 0.01 0.01"/></geometry></collision></link><joint '
                                                  'name="hinge" type="revolute"><parent link="base"/><child '
                                                  'link="lid"/><axis xyz="0 0 1"/></joint>')),
     "joint 'hinge' (revolute) moves"),
])
def test_a_bad_urdf_is_one_line_and_writes_nothing(tmp_path: Path, change: object, needle: str) -> None:
    urdf = write_urdf(tmp_path)
    (tmp_path / "meshes" / "brick.dae").write_text("<COLLADA/>")
    change(urdf)  # type: ignore[operator]
    db = tmp_path / "g.db"
    code, _, err = generate(db, str(urdf))
    one_line_error(code, err, 2, needle)
    assert not db.exists()


@pytest.mark.parametrize("own, given", [('value="0"', "--mass"), ("", "--friction")])
def test_a_urdf_planned_over_its_refused_value_is_found_by_its_file(tmp_path: Path, own: str, given: str) -> None:
    """A URDF whose own mass (0, PyBullet's fixed body) or links' frictions (two, apart) are refused, planned with
    --mass or --friction: best and show find it by its file, and a hand without grasps of it is told the command
    that plans it at the stored value, rather than the URDF's refusal."""
    urdf = write_urdf(tmp_path)
    if own:
        urdf.write_text(urdf.read_text().replace('value="0.25"', own))
    else:
        urdf.write_text(urdf.read_text().replace("</robot>", '<link name="tag"><contact><lateral_friction value="0.4"/>'
                                                 '</contact><collision><origin xyz="0 0 0.05"/><geometry><box size='
                                                 '"0.01 0.01 0.01"/></geometry></collision></link><joint name="glued" '
                                                 'type="fixed"><parent link="base"/><child link="tag"/></joint>'
                                                 "</robot>"))
    db = tmp_path / "g.db"
    value = "0.5" if given == "--mass" else "0.7"
    code, _, err = generate(db, str(urdf), given, value)
    assert code == 0, err
    for command in (("best", str(urdf)), ("show", str(urdf), "--out", str(tmp_path / "g.png"))):
        code, out, err = grasp(*command, "--hand", "panda", "--db", str(db))
        assert code == 0, (out, err)
    code, _, err = grasp("best", str(urdf), "--hand", "barrett", "--db", str(db))
    one_line_error(code, err, 2, "no grasps of 'brick' for hand 'barrett'", f"grasp generate {urdf} --hand barrett ",
                   f" {given} {value} ")


def test_a_urdf_linked_from_a_content_store_finds_its_meshes_beside_the_link(tmp_path: Path) -> None:
    """A folder of links into a content store (git-annex: each file alone in its own folder): the URDF's meshes
    are beside the link that names it, as PyBullet finds them, not beside the file it leads to. It is stored
    as that link, from which show and export rebuild it."""
    store = write_urdf(tmp_path / "store")
    key = tmp_path / "annex" / "SHA256E-s1--k.urdf"
    key.parent.mkdir()
    store.rename(key)
    folder = tmp_path / "dataset"
    (folder / "meshes").mkdir(parents=True)
    (folder / "brick.urdf").symlink_to(key)
    (folder / "meshes" / "brick.obj").symlink_to(tmp_path / "store" / "meshes" / "brick.obj")
    db = tmp_path / "g.db"
    code, _, err = generate(db, str(folder / "brick.urdf"))
    assert code == 0, err
    assert stored(db)[:2] == ("brick", str(folder.resolve() / "brick.urdf"))
    code, _, err = generate(db, str(folder))  # the folder's walk: the same object, done
    assert code == 0, err
    code, _, err = grasp("export", "--db", str(db), "--format", "acronym", "--out", str(tmp_path / "out"))
    assert code == 0, err
    exported = load_mesh_file(tmp_path / "out" / "meshes" / "brick.obj")
    assert np.allclose(exported.bounds, PLACED, atol=EXPORT_TOL), exported.bounds
    (tmp_path / "linked").symlink_to(folder)  # the same link through a linked folder: the same object
    for named in (folder / "brick.urdf", tmp_path / "linked" / "brick.urdf"):
        code, _, err = grasp("best", str(named), "--hand", "panda", "--db", str(db))
        assert code == 0, err


def test_a_urdf_without_inertial_gets_the_default_mass_as_a_mesh_does(tmp_path: Path) -> None:
    """Made 3 x 5 x 7 mm, at the default 0.2 kg: the density note a mesh of that size gets."""
    urdf = write_urdf(tmp_path, scale="0.1")
    urdf.write_text(urdf.read_text().replace('<inertial><origin xyz="0 0 0.02"/><mass value="0.25"/></inertial>', ""))
    db = tmp_path / "g.db"
    code, _, err = grasp("generate", str(urdf), "--hand", "panda", "--db", str(db), *FAST)
    assert code == 0, err
    assert stored(db)[3:5] == (0.2, 0.9)
    mesh = tmp_path / "meshes" / "brick.obj"
    code, _, mesh_err = grasp("generate", str(mesh), "--hand", "panda", "--db", str(tmp_path / "m.db"), "--scale",
                              "0.1", *FAST)
    assert code == 0, mesh_err
    note = "note: brick weighs 0.2 kg in its volume: 1.9e+06 kg/m^3, outside any solid's"
    assert note in err and note in mesh_err, (err, mesh_err)
