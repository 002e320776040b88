"""A user's URDF file as an object: its geometry placed as the URDF places it
(mesh scale, origins, fixed joints, primitives), its mass and friction read as
PyBullet reads them, and the refusals, each one line."""

from __future__ import annotations

import logging
import math
import os
from pathlib import Path

import numpy as np
import pytest
import trimesh
from helpers import assert_close

from planner import assets, prepare
from planner.errors import ConfigError, InputError, MeshError
from planner.geometry.solid import load_object
from planner.specs import inputs
from planner.specs.object_files import edited_since
from planner.specs.objects import DEFAULT_FRICTION, DEFAULT_MASS, URDF_FILE, file_scale, resolve_spec
from planner.specs.physical import MAX_FRICTION
from planner.specs.urdf_objects import read_urdf_object

BRICK = (0.02, 0.04, 0.06)  # [m] extents of the test mesh, all different so a turn shows
#: Tolerance of placed vertices [m]: an rpy of a quarter turn is exact to cos(pi/2) ~ 6e-17.
PLACE_TOL = 1e-9


def brick(folder: Path, name: str = "brick.obj", extents: tuple[float, ...] = BRICK) -> Path:
    path = folder / name
    path.parent.mkdir(parents=True, exist_ok=True)
    trimesh.creation.box(extents=extents).export(path)
    return path


def element(geometry: str, xyz: str = "0 0 0", rpy: str = "0 0 0", tag: str = "collision") -> str:
    return f"<{tag}><origin xyz='{xyz}' rpy='{rpy}'/><geometry>{geometry}</geometry></{tag}>"


def link(name: str, *elements: str, mass: float | None = None, friction: float | None = None) -> str:
    contact = "" if friction is None else f"<contact><lateral_friction value='{friction}'/></contact>"
    inertial = "" if mass is None else f"<inertial><mass value='{mass}'/></inertial>"
    return f"<link name='{name}'>{contact}{inertial}{''.join(elements)}</link>"


def joint(parent: str, child: str, xyz: str = "0 0 0", rpy: str = "0 0 0", kind: str = "fixed") -> str:
    return (f"<joint name='{parent}_{child}' type='{kind}'><parent link='{parent}'/><child link='{child}'/>"
            f"<origin xyz='{xyz}' rpy='{rpy}'/><axis xyz='0 0 1'/></joint>")


def write(folder: Path, *parts: str, name: str = "obj") -> Path:
    path = folder / f"{name}.urdf"
    path.write_text(f"<?xml version='0.0'?>\n<robot name='{name}'>{''.join(parts)}</robot>")
    return path


def test_a_mesh_is_placed_by_its_origin_and_scale_and_the_urdf_gives_mass_and_friction(tmp_path: Path) -> None:
    """Scaled by 0.5 (0.01 x 0.02 x 0.03), turned a quarter about x (y to z: 0.01 x 0.03 x 0.02), moved 0.1 m
    along x: the object frame is the link frame."""
    brick(tmp_path / "meshes")
    urdf = write(tmp_path, link("base", element("<mesh filename='meshes/brick.obj' scale='0.5 0.5 0.5'/>",
                                                 xyz="0.1 0 0", rpy=f"{math.pi / 2} 0 0"), mass=0.25, friction=0.9))
    obj = load_object(str(urdf))
    assert_close(obj.mesh.bounds, [[0.095, -0.015, -0.01], [0.105, 0.015, 0.01]], PLACE_TOL)
    assert (obj.spec.kind, obj.mass, obj.friction, obj.spec.density) == (URDF_FILE, 0.25, 0.9, None)
    assert (obj.source_file, obj.file_scale) == (str(urdf), 1.0)
    scaled = load_object(str(urdf), scale=2.0)  # --scale scales the whole about the link frame's origin
    assert_close(scaled.mesh.bounds, 2 * obj.mesh.bounds, PLACE_TOL)
    assert scaled.file_scale == 2.0 == file_scale(scaled.spec)


def test_package_absolute_and_file_paths_name_the_mesh(tmp_path: Path) -> None:
    mesh = brick(tmp_path / "pkg" / "meshes")
    folder = tmp_path / "pkg" / "urdf"
    folder.mkdir()
    for name, filename in (("package", "package://pkg/meshes/brick.obj"), ("absolute", str(mesh)),
                           ("file", f"file://{mesh}")):
        urdf = write(folder, link("base", element(f"<mesh filename='{filename}'/>")), name=name)
        assert read_urdf_object(urdf).files == (mesh,)
        assert_close(load_object(str(urdf)).mesh.extents, BRICK, PLACE_TOL)
    lost = write(folder, link("base", element("<mesh filename='package://other/brick.obj'/>")), name="lost")
    with pytest.raises(ConfigError, match=r"lost.urdf: link 'base': mesh file not found: package://other/brick.obj "
                                          r"\(looked at .*\) \(a package:// path is looked for from the URDF's folder"):
        resolve_spec(str(lost))


def test_a_non_uniform_mesh_scale_scales_each_axis(tmp_path: Path) -> None:
    brick(tmp_path)
    urdf = write(tmp_path, link("base", element("<mesh filename='brick.obj' scale='1 2 0.5'/>")))
    assert_close(load_object(str(urdf)).mesh.extents, [0.02, 0.08, 0.03], PLACE_TOL)


def test_primitives_are_made_as_meshes_along_their_axes(tmp_path: Path) -> None:
    """A box of known volume; a cylinder along its z, turned onto x; a sphere; the three apart, one object."""
    turned = f"0 {math.pi / 2} 0"
    urdf = write(tmp_path, link("base", element("<box size='0.02 0.04 0.06'/>"),
                                element("<cylinder radius='0.01' length='0.08'/>", xyz="0.1 0 0", rpy=turned),
                                element("<sphere radius='0.02'/>", xyz="0 0.1 0")))
    obj = load_object(str(urdf))
    parts = sorted(obj.mesh.split(only_watertight=False), key=lambda m: tuple(np.round(m.centroid, 6)))
    box, sphere, cylinder = parts[0], parts[1], parts[2]
    assert_close(box.extents, [0.02, 0.04, 0.06], PLACE_TOL)
    assert_close(cylinder.extents[0], 0.08, PLACE_TOL)  # its length along x after the turn
    assert_close(sphere.centroid, [0, 0.1, 0], 1e-4)
    assert box.volume == pytest.approx(0.02 * 0.04 * 0.06, rel=1e-9)
    assert cylinder.volume == pytest.approx(math.pi * 0.01**2 * 0.08, rel=0.01)  # 48 sections


def test_links_joined_by_fixed_joints_are_merged_where_their_chains_put_them(tmp_path: Path) -> None:
    """Three links: b 0.1 m along the base's x, c turned a quarter about z on b and 0.05 m along b's y; two
    collision elements in the base. Each box lands where its chain puts it."""
    box = "<box size='0.02 0.02 0.02'/>"
    urdf = write(tmp_path, link("base", element(box), element(box, xyz="0 0 0.05"), mass=0.1),
                 link("b", element(box), mass=0.2), link("c", element("<box size='0.04 0.02 0.02'/>"), mass=0.05),
                 joint("base", "b", xyz="0.1 0 0"), joint("b", "c", xyz="0 0.05 0", rpy="0 0 1.5707963267948966"))
    own = read_urdf_object(urdf)
    assert [p.link for p in own.parts] == ["base", "base", "b", "c"] and own.mass == pytest.approx(0.35)
    centres = sorted(tuple(np.round(p.pose[:3, 3], 9)) for p in own.parts)
    assert centres == [(0, 0, 0), (0, 0, 0.05), (0.1, 0, 0), (0.1, 0.05, 0)]
    c = own.parts[-1].pose
    assert_close(c[:3, :3] @ [1, 0, 0], [0, 1, 0], PLACE_TOL)  # c's x (its 4 cm side) along the base's y
    obj = load_object(str(urdf))
    assert obj.mass == pytest.approx(0.35)
    assert_close(obj.mesh.bounds, [[-0.01, -0.01, -0.01], [0.11, 0.07, 0.06]], PLACE_TOL)


@pytest.mark.parametrize("extra, message", [
    (joint("base", "lid", kind="revolute"), "joint 'base_lid' (revolute) moves: an articulated object"),
    (joint("base", "lid", kind="prismatic"), "(prismatic) moves"),
    (joint("base", "lid", kind="floating"), "(floating) moves"),
    ("", "links base, lid are joined to none above them: one object is one tree of links"),
    (joint("base", "lid") + joint("lid", "base"), "its joints make a loop"),
    (joint("lid", "tip") + joint("tip", "lid") + link("tip"), "links lid, tip are not joined to base"),
])
def test_an_articulated_or_disjoint_urdf_is_refused_in_one_line(tmp_path: Path, extra: str, message: str) -> None:
    box = element("<box size='0.02 0.02 0.02'/>")
    urdf = write(tmp_path, link("base", box), link("lid", box), extra)
    with pytest.raises(ConfigError, match=re_escaped(message)) as info:
        resolve_spec(str(urdf))
    assert "\n" not in str(info.value)


def re_escaped(text: str) -> str:
    import re

    return re.escape(text)


def test_the_visual_geometry_stands_in_for_a_missing_collision_one_with_a_note(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    brick(tmp_path)
    urdf = write(tmp_path, link("base", element("<mesh filename='brick.obj'/>", tag="visual")))
    assert resolve_spec(str(urdf)).geometry == "visual"
    with caplog.at_level(logging.INFO, logger=prepare.LOGGER):
        assert_close(load_object(str(urdf)).mesh.extents, BRICK, PLACE_TOL)
    assert any("no <collision> element: its <visual> geometry is planned on" in r.getMessage()
               for r in caplog.records)
    both = write(tmp_path, link("base", element("<mesh filename='brick.obj'/>", tag="visual"),
                                element("<box size='0.01 0.01 0.01'/>")), name="both")
    assert_close(load_object(str(both)).mesh.extents, [0.01] * 3, PLACE_TOL)  # the collision shape, not the visual


@pytest.mark.parametrize("body, message", [
    ("<link name='a'><collision><geometry><box size='1 1 1'/></geometry></link>", "malformed URDF"),
    (link("a", element("<mesh filename='gone.obj'/>")), "link 'a': mesh file not found: gone.obj"),
    (link("a", element("<mesh filename='meshes\\brick.obj'/>")), "(a Windows path? write / between folders)"),
    (link("a", element("<mesh filename='brick.dae'/>")), "link 'a': brick.dae: unsupported mesh type '.dae'"),
    (link("a", element("<capsule radius='0.1' length='0.2'/>")), "link 'a': <capsule> geometry is not supported"),
    (link("a", element("<box size='0.1 -1 0.1'/>")), "<box> needs positive lengths"),
    (link("a", element("<mesh filename='brick.obj' scale='1 0 1'/>")), "<mesh scale> must be one or three positive"),
    (link("a", element("<box size='0.05 0.05 0.05'/>"), mass=0), "<inertial><mass>: mass must be a positive number "
                                                                  "[kg], got 0.0 (PyBullet's mark of a fixed body); "
                                                                  "give the object's own with --mass"),
    (link("a", element("<box size='0.05 0.05 0.05'/>"), mass=-1), "got -1.0; give the object's own with --mass"),
    (link("a", element("<box size='0.05 0.05 0.05'/>"), friction=MAX_FRICTION + 1),
     "<contact><lateral_friction>: friction must lie in (0, 3]"),
    (link("a", element("<box size='0.05 0.05 0.05'/>"), friction=0), "friction must be a positive number"),
    ("<link name='a'><contact><lateral_friction/></contact>" + element("<box size='0.05 0.05 0.05'/>") + "</link>",
     "<lateral_friction> needs a number value, got None"),
    (link("a", element("<box size='0.05 0.05 0.05'/>"), friction=0.5)
     + link("b", element("<box size='0.05 0.05 0.05'/>"), friction=0.8) + joint("a", "b"),
     "its links' <lateral_friction> differ (a 0.5, b 0.8; "),
    (link("a"), "no link has a <collision> or <visual> geometry"),
    ("", "no link has a <collision> or <visual> geometry"),  # no link at all: not "its joints make a loop"
])
def test_bad_urdfs_are_refused_in_one_line(tmp_path: Path, body: str, message: str) -> None:
    brick(tmp_path)
    (tmp_path / "brick.dae").write_text("<COLLADA/>")
    urdf = write(tmp_path, body)
    with pytest.raises(InputError, match=re_escaped(message)) as info:
        resolve_spec(str(urdf))
    assert "\n" not in str(info.value) and str(urdf) in str(info.value)


def test_the_run_a_sidecar_and_the_urdf_give_values_in_that_order(tmp_path: Path) -> None:
    urdf = write(tmp_path, link("a", element("<box size='0.05 0.05 0.05'/>"), mass=0.1, friction=1.0))
    assert (resolve_spec(str(urdf)).mass, resolve_spec(str(urdf)).friction) == (0.1, 1.0)
    urdf.with_suffix(".toml").write_text("mass = 0.2\n")
    spec = resolve_spec(str(urdf))
    assert (spec.mass, spec.friction) == (0.2, 1.0)  # the sidecar's mass, the URDF's friction
    spec = resolve_spec(str(urdf), density=500.0, friction=0.7)
    assert (spec.density, spec.friction) == (500.0, 0.7)
    urdf.with_suffix(".toml").unlink()
    assert resolve_spec(str(urdf), mass=0.3).mass == 0.3


def test_a_value_another_source_replaces_is_not_read(tmp_path: Path) -> None:
    """A tray's mass 0 (PyBullet's fixed body) and links of different frictions are refused only where used."""
    box = element("<box size='0.05 0.05 0.05'/>")
    urdf = write(tmp_path, link("a", box, mass=0, friction=0.5), link("b", box, friction=0.8), joint("a", "b"))
    spec = resolve_spec(str(urdf), mass=0.4, friction=0.6)
    assert (spec.mass, spec.friction) == (0.4, 0.6)


def test_a_urdf_without_inertial_or_contact_gets_the_defaults(tmp_path: Path) -> None:
    urdf = write(tmp_path, link("a", element("<box size='0.05 0.05 0.05'/>")))
    spec = resolve_spec(str(urdf))
    assert (spec.mass, spec.friction, spec.density) == (DEFAULT_MASS, DEFAULT_FRICTION, None)
    own = read_urdf_object(urdf)
    assert own.mass is None and own.frictions == () and own.stated() == {}


def test_an_edit_of_the_urdf_or_of_its_mesh_is_seen(tmp_path: Path) -> None:
    mesh = brick(tmp_path)
    urdf = write(tmp_path, link("a", element("<mesh filename='brick.obj'/>")))
    finished = max(urdf.stat().st_mtime, mesh.stat().st_mtime) + 1
    assert not edited_since(urdf, finished)
    for edited in (urdf, mesh):
        now = finished + 10
        os.utime(edited, (now, now))
        assert edited_since(urdf, finished)
        os.utime(edited, (finished - 1, finished - 1))
    mesh.unlink()
    assert edited_since(urdf, finished)  # its mesh gone: it cannot be the one stored


def test_a_folder_or_glob_takes_each_urdf_and_the_meshes_no_urdf_names(tmp_path: Path) -> None:
    """pybullet_data's layout: duck.urdf names duck.obj (visual) and duck_vhacd.obj (collision); cup.obj stands
    alone. Three mesh files, two objects: the duck from its URDF (its scale, mass, friction), the cup."""
    for name in ("duck.obj", "duck_vhacd.obj", "cup.obj"):
        brick(tmp_path / "objects", name)
    write(tmp_path / "objects", link("base", element("<mesh filename='duck.obj'/>", tag="visual"),
                                     element("<mesh filename='duck_vhacd.obj' scale='0.5'/>")), name="duck")
    assert sorted(Path(r.source).name for r in inputs.expand([str(tmp_path / "objects")])) == ["cup.obj", "duck.urdf"]
    assert sorted(Path(r.source).name for r in inputs.expand([str(tmp_path / "objects" / "*")])) == \
        ["cup.obj", "duck.urdf"]
    assert [r.name for r in inputs.expand([str(tmp_path / "objects" / "*.obj")])] == ["cup", "duck", "duck_vhacd"]


def test_a_manifest_line_names_a_urdf_and_its_columns_win(tmp_path: Path) -> None:
    urdf = write(tmp_path, link("a", element("<box size='0.05 0.05 0.05'/>"), mass=0, friction=1.0), name="tray")
    (tmp_path / "m.txt").write_text("tray.urdf 2 mass=0.3\n")
    (ref,) = inputs.expand([f"@{tmp_path / 'm.txt'}"])
    assert (ref.source, ref.scale, ref.physical.mass) == (str(urdf), 2.0, 0.3)
    (tmp_path / "m.txt").write_text("box\ntray.urdf\n")
    with pytest.raises(InputError, match=re_escaped("m.txt:2: ") + ".*tray.urdf <inertial><mass>: mass must be"):
        inputs.expand([f"@{tmp_path / 'm.txt'}"])


def test_a_registry_urdf_is_its_one_mesh_at_its_scale() -> None:
    duck = read_urdf_object(assets.pybullet_data_root() / "duck_vhacd.urdf")
    path, scale = duck.single_mesh()
    assert path.name == "duck_vhacd.obj" and scale == 0.05
    assert (duck.mass, duck.frictions) == (0.1, (("baseLink", 1.0),))


@pytest.mark.parametrize("mesh, message", [('<mesh filename="m.obj" scale="1 2 1"/>', "non-uniform mesh scale"),
                                           ("<box size='1 1 1'/>", "needs a <visual> mesh")])
def test_registry_urdfs_we_cannot_store_as_one_mesh(tmp_path: Path, mesh: str, message: str) -> None:
    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    urdf = tmp_path / "o.urdf"
    urdf.write_text(f"<robot name='o'><link name='l'><visual><geometry>{mesh}</geometry></visual></link></robot>")
    with pytest.raises((ConfigError, MeshError), match=message):
        read_urdf_object(urdf, "visual").single_mesh()
