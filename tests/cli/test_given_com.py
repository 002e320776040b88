"""``grasp generate`` of a URDF with its own centre of mass, end to end: stored, measured about, handed to the
trials and the exports; one outside the object refused; a URDF planned on its visual elements, kept apart."""

from __future__ import annotations

import sqlite3
from dataclasses import replace
from pathlib import Path

import h5py
import numpy as np
import pytest
from helpers import FAST, assert_close, grasp, one_line_error

from planner.db.objects import stored_object
from planner.db.store import open_db

SIZE = (0.04, 0.06, 0.1)  # [m] the box the URDFs are made of
#: [m] the grip measures are stored to 0.1 um (vectors) and as REAL: a shift agrees to round-off of both.
MEASURE_TOL = 1e-9


def box_urdf(folder: Path, xyz: str, name: str = "box", visual: str = "") -> Path:
    path = folder / f"{name}.urdf"
    path.write_text(f"""<robot name="{name}"><link name="base">
  <inertial><origin xyz="{xyz}"/><mass value="0.2"/>
    <inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial>
  <collision><geometry><box size="{' '.join(map(str, SIZE))}"/></geometry></collision>{visual}</link></robot>""")
    return path


def generate(db: Path, *args: str) -> tuple[int, str, str]:
    return grasp("generate", *args, "--hand", "panda", "--db", str(db), "--quiet", "--reach-placements", "0",
                 *FAST[:-2])


def rows(db: Path, sql: str) -> list[tuple]:
    with sqlite3.connect(db) as conn:
        return conn.execute(sql).fetchall()


def test_a_declared_com_is_stored_and_moves_com_height_by_its_offset(tmp_path: Path) -> None:
    """The same box, its centre of mass at its middle and 3 cm up: the grasps that are the same pose in both
    have their com_height 3 cm apart (the object's up +z), and the stored com is the URDF's."""
    heights = {}
    for name, xyz in (("mid", "0 0 0"), ("high", "0.01 0 0.03")):
        db = tmp_path / f"{name}.db"
        (tmp_path / name).mkdir()
        code, _, err = generate(db, str(box_urdf(tmp_path / name, xyz)))  # one name: the same seeds
        assert code == 0, err
        (com,) = rows(db, "SELECT com FROM objects")[0]
        assert_close(np.array(eval(com)), [float(v) for v in xyz.split()])
        heights[name] = dict(rows(db, "SELECT pose, com_height FROM grasps WHERE com_height IS NOT NULL"))
    same = set(heights["mid"]) & set(heights["high"])
    assert same, "no grasp planned at one pose in both"
    for pose in same:
        assert heights["high"][pose] - heights["mid"][pose] == pytest.approx(0.03, abs=MEASURE_TOL)


def test_the_stored_com_reaches_the_trials_and_the_export(tmp_path: Path) -> None:
    from planner.specs.hands import load_hand
    from planner.validation.mujoco_settings import MujocoSettings
    from planner.validation.mujoco_worlds import world_for

    db = tmp_path / "g.db"
    assert generate(db, str(box_urdf(tmp_path, "0.01 -0.02 0.03")))[0] == 0
    with open_db(db) as store:
        row = store.object_row("box")
    assert row is not None
    obj = stored_object(row)
    assert_close(obj.com, [0.01, -0.02, 0.03])
    world = world_for(load_hand("panda"), obj, MujocoSettings(), obj.mass)
    assert_close(world.model.body_ipos[world.object_body], [0.01, -0.02, 0.03])
    # the same mesh as another object (its centre elsewhere) in the same process: a world of its own
    other = replace(obj, com=np.zeros(3))
    world = world_for(load_hand("panda"), other, MujocoSettings(), obj.mass)
    assert_close(world.model.body_ipos[world.object_body], np.zeros(3))
    code, _, err = grasp("export", "--db", str(db), "--format", "acronym", "--out", str(tmp_path / "out"))
    assert code == 0, err
    with h5py.File(tmp_path / "out" / "box__panda.h5") as f:
        assert_close(f["object/com"][()], [0.01, -0.02, 0.03])
    code, out, err = grasp("validate", "--db", str(db), "--object", "box", "--hand", "panda", "--top", "2")
    assert code == 0 and "validated 2 grasps" in out, (out, err)


def test_an_exported_com_and_inertia_come_back_with_grasp_import(tmp_path: Path) -> None:
    """Our own ACRONYM file of an object whose centre of mass and inertia were given (not its mesh's) is imported
    with them (its grasps' measures were of those), also from a moved copy; a file of the mesh's own com as
    before."""
    import shutil

    db, urdf = tmp_path / "g.db", box_urdf(tmp_path, "0.01 -0.02 0.03")
    urdf.write_text(urdf.read_text().replace('ixx="1" iyy="1" izz="1"', 'ixx="1e-4" iyy="1.2e-4" izz="0.8e-4"'))
    assert generate(db, str(urdf))[0] == 0
    assert grasp("export", "--db", str(db), "--format", "acronym", "--out", str(tmp_path / "out"), "--quiet")[0] == 0
    shutil.copytree(tmp_path / "out", tmp_path / "moved")
    code, _, err = grasp("import", "--format", "acronym", str(tmp_path / "moved" / "box__panda.h5"),
                         "--db", str(tmp_path / "back.db"))
    assert code == 0, err
    (exported,) = rows(db, "SELECT com, inertia FROM objects")
    (back,) = rows(tmp_path / "back.db", "SELECT com, inertia FROM objects")
    assert_close(np.array(eval(back[0])), [0.01, -0.02, 0.03])
    code, out, _ = grasp("db", "objects", "--db", str(tmp_path / "back.db"))
    assert code == 0 and "centre of mass (10, -20, 30) mm" in out, out
    assert_close(np.ravel(eval(back[1])), np.ravel(eval(exported[1])))
    assert_close(np.ravel(eval(back[1])), np.diag([1e-4, 1.2e-4, 0.8e-4]).ravel())  # the URDF's, not the mesh's


def test_a_com_outside_the_object_is_refused_in_one_line_and_nothing_written(tmp_path: Path) -> None:
    db = tmp_path / "g.db"
    code, _, err = generate(db, str(box_urdf(tmp_path, "0 0 0.2")))
    one_line_error(code, err, 2, "box.urdf: its centre of mass [0, 0, 0.2] m (box.urdf <inertial><origin>) lies "
                                 "150 mm outside the object's convex hull")
    assert not db.exists()


def test_a_sidecar_com_replacing_the_urdfs_is_said_and_another_one_later_refused(tmp_path: Path) -> None:
    urdf = box_urdf(tmp_path, "0 0 0.01")
    urdf.with_suffix(".toml").write_text("com = [0, 0, 0.02]\n")
    db = tmp_path / "g.db"
    code, _, err = grasp("generate", str(urdf), "--hand", "panda", "--db", str(db), *FAST)
    assert code == 0, err
    assert "object 'box': com [0, 0, 0.02] from box.toml replaces box.urdf's com [0, 0, 0.01]" in err
    urdf.with_suffix(".toml").unlink()
    code, _, err = generate(db, str(urdf))
    one_line_error(code, err, 2, "object 'box' is stored", "with its centre of mass at [0, 0, 0.02] m",
                   "now [0, 0, 0.01], given by box.urdf <inertial><origin>")


@pytest.mark.parametrize("change", ["com taken out of the sidecar", "sidecar removed"])
def test_a_sidecar_com_no_more_given_is_refused_once_every_unit_is_done(tmp_path: Path, change: str) -> None:
    """A mesh's sidecar com taken out (or the sidecar, which gave only it, removed) after the whole sweep was
    stored: the re-run added nothing and said nothing, the stored object keeping the sidecar's centre; a changed
    one was refused. Now both are: the mesh's own centre is not the one its grasps were planned about."""
    mesh = tmp_path / "banana.obj"
    mesh.write_text("".join(f"v {x} {y} {z}\n" for x in (-0.02, 0.02) for y in (-0.03, 0.03) for z in (-0.05, 0.05))
                    + "f 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\n")
    sidecar = mesh.with_suffix(".toml")
    sidecar.write_text("friction = 0.5\ncom = [0, 0, 0.02]\n")
    db = tmp_path / "g.db"
    assert generate(db, str(mesh))[0] == 0
    if change == "sidecar removed":
        sidecar.unlink()
    else:
        sidecar.write_text("friction = 0.5\n")
    code, _, err = generate(db, str(mesh))
    one_line_error(code, err, 2, "object 'banana' is stored", "with its centre of mass at [0, 0, 0.02] m",
                   "now [0, 0, 0], the mesh's")


def test_a_manifest_com_no_more_given_is_refused_once_every_unit_is_done(tmp_path: Path) -> None:
    """The same for a manifest line's ``com=`` taken out: the manifest's time was not read, so the re-run added
    nothing and said nothing (the stored object keeping the line's centre). The mesh in a folder of its own: the
    database's files beside it would make its folder's time new (read where it has no sidecar)."""
    (tmp_path / "m").mkdir()
    mesh = tmp_path / "m" / "banana.obj"
    mesh.write_text("".join(f"v {x} {y} {z}\n" for x in (-0.02, 0.02) for y in (-0.03, 0.03) for z in (-0.05, 0.05))
                    + "f 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\n")
    manifest = tmp_path / "list.txt"
    manifest.write_text("m/banana.obj com=0,0,0.02\n")
    db = tmp_path / "g.db"
    assert generate(db, f"@{manifest}")[0] == 0
    assert generate(db, f"@{manifest}")[0] == 0  # unchanged: nothing to do
    manifest.write_text("m/banana.obj\n")
    code, _, err = generate(db, f"@{manifest}")
    one_line_error(code, err, 2, "object 'banana' is stored", "with its centre of mass at [0, 0, 0.02] m",
                   "now [0, 0, 0], the mesh's")
    manifest.write_text("m/banana.obj com=0,0,0.03\n")  # another one: said as given (it read "given by as given")
    code, _, err = generate(db, f"@{manifest}")
    one_line_error(code, err, 2, "with its centre of mass at [0, 0, 0.02] m", "(now [0, 0, 0.03], as given, and")


def test_under_scale_a_sidecar_com_is_compared_with_the_urdfs_scaled(tmp_path: Path) -> None:
    """A sidecar's centre is the scaled object's: at --scale 2 it equals a URDF's own at half its value (nothing
    replaced, nothing said), and where it differs the URDF's is said as the scaled object has it."""
    urdf = box_urdf(tmp_path, "0 0 0.01")
    urdf.with_suffix(".toml").write_text("com = [0, 0, 0.02]\n")
    code, _, err = grasp("generate", str(urdf), "--scale", "2", "--hand", "panda", "--db", str(tmp_path / "a.db"),
                         *FAST)
    assert code == 0, err
    assert "replaces" not in err, err
    urdf.with_suffix(".toml").write_text("com = [0, 0, 0.03]\n")
    code, _, err = grasp("generate", str(urdf), "--scale", "2", "--hand", "panda", "--db", str(tmp_path / "b.db"),
                         *FAST)
    assert code == 0, err
    assert "com [0, 0, 0.03] from box.toml replaces box.urdf's com [0, 0, 0.02]" in err, err


def test_the_visual_geometry_is_planned_stored_and_kept_apart(tmp_path: Path) -> None:
    """A URDF whose collision box is a stand-in for a smaller visual one: --geometry visual plans on the visual
    box; the other choice under the same name is refused, not mixed in; validate rebuilds the visual one."""
    visual = '<visual><geometry><box size="0.03 0.05 0.08"/></geometry></visual>'
    urdf = box_urdf(tmp_path, "0 0 0", visual=visual)
    db = tmp_path / "g.db"
    code, _, err = generate(db, str(urdf), "--geometry", "visual")
    assert code == 0, err
    ((geometry, volume),) = rows(db, "SELECT geometry, volume FROM objects")
    assert geometry == "visual" and volume == pytest.approx(0.03 * 0.05 * 0.08)
    code, out, _ = grasp("db", "objects", "--db", str(db))
    assert code == 0 and out.rstrip().endswith("box.urdf (its <visual> elements)"), out
    code, out, err = grasp("generate", str(urdf), "--hand", "panda", "--db", str(db), "--json", "--geometry", "visual",
                           "--reach-placements", "0", *FAST[:-2])
    assert code == 0 and '"skipped": 1' in out, err
    code, _, err = generate(db, str(urdf))
    one_line_error(code, err, 2, "object 'box' is stored", "of its <visual> elements, now of its <collision>",
                   "give --geometry visual")
    code, out, err = grasp("validate", "--db", str(db), "--object", "box", "--hand", "panda", "--top", "1")
    assert code == 0 and "validated 1 grasps" in out, (out, err)
    code, _, err = generate(tmp_path / "m.db", str(tmp_path / "missing.obj"), "--geometry", "visual")
    assert code == 2


def test_the_store_refuses_a_unit_of_another_com(tmp_path: Path) -> None:
    """Two runs of one object with other centres of mass (or inertias) at once: the second's units are refused when
    written (the check at a run's start cannot see the other run), nothing of them stored."""
    from planner.db.rows import UnitRow
    from planner.errors import InputError
    from planner.geometry.solid import load_object

    db = tmp_path / "g.db"
    assert generate(db, "box")[0] == 0
    box = load_object("box")
    stored = rows(db, "SELECT count(*) FROM units")
    with open_db(db) as store:
        for other in (replace(box, com=np.asarray(box.com) + [0, 0, 0.01]),
                      replace(box, inertia=np.asarray(box.inertia) * 1.1)):
            with pytest.raises(InputError, match="with another centre of mass or inertia than this unit's"):
                store.write_unit(UnitRow("box", "panda", "x", "{}", 0, 99), other, [], store.rule())
        assert_close(store.object_row("box").com, box.com)  # type: ignore[union-attr]
    assert rows(db, "SELECT count(*) FROM units") == stored


def test_an_exported_inertia_about_the_meshs_com_comes_back_with_grasp_import(tmp_path: Path) -> None:
    """A URDF whose <inertial> origin is its link origin (no declared centre: the mesh's, here the box's middle)
    and whose plausible <inertia> is stored: our own exported file gives it back on import (its com is the mesh's,
    its inertia not)."""
    db, urdf = tmp_path / "g.db", box_urdf(tmp_path, "0 0 0")
    urdf.write_text(urdf.read_text().replace('ixx="1" iyy="1" izz="1"', 'ixx="1e-4" iyy="1.2e-4" izz="0.8e-4"'))
    assert generate(db, str(urdf))[0] == 0
    assert grasp("export", "--db", str(db), "--format", "acronym", "--out", str(tmp_path / "out"), "--quiet")[0] == 0
    code, _, err = grasp("import", "--format", "acronym", str(tmp_path / "out" / "box__panda.h5"),
                         "--db", str(tmp_path / "back.db"))
    assert code == 0, err
    (back,) = rows(tmp_path / "back.db", "SELECT com, inertia FROM objects")
    assert_close(np.array(eval(back[0])), np.zeros(3))
    assert_close(np.ravel(eval(back[1])), np.diag([1e-4, 1.2e-4, 0.8e-4]).ravel())  # the URDF's, not the mesh's


def test_an_edited_visual_mesh_is_seen_when_the_object_is_of_its_visual_elements(tmp_path: Path) -> None:
    """A URDF planned on its <visual> mesh, that mesh edited since (its collision box not): a run whose units
    are all done is refused (not skipped as unchanged), and ``best`` is told the mesh was modified."""
    import os

    import trimesh

    from planner import api

    trimesh.creation.box((0.03, 0.05, 0.08)).export(tmp_path / "shape.obj")
    urdf = box_urdf(tmp_path, "0 0 0", visual='<visual><geometry><mesh filename="shape.obj"/></geometry></visual>')
    db = tmp_path / "g.db"
    assert generate(db, str(urdf), "--geometry", "visual")[0] == 0
    assert api.mesh_modified("box", db_path=db) is None
    trimesh.creation.box((0.03, 0.05, 0.07)).export(tmp_path / "shape.obj")
    later = os.stat(urdf).st_mtime + 5  # after the last unit finished, whatever the clock's resolution
    os.utime(tmp_path / "shape.obj", (later, later))
    assert api.mesh_modified("box", db_path=db) == str(urdf)
    code, _, err = generate(db, str(urdf), "--geometry", "visual")
    one_line_error(code, err, 2, "object 'box' is stored", "from another mesh")


def test_db_objects_says_visual_elements_of_a_urdf_file_only(tmp_path: Path) -> None:
    """The built-in mug is stored as the visual mesh its registry URDF names (geometry 'visual'): its line names
    that mesh and nothing of elements."""
    db = tmp_path / "m.db"
    assert generate(db, "mug")[0] == 0
    code, out, _ = grasp("db", "objects", "--db", str(db))
    assert code == 0 and out.rstrip().endswith("mug.obj"), out
