"""An object's centre of mass as given: a URDF's <inertial> origins (times --scale), a sidecar's com, a manifest's
com= column, first first, the prepared object planned about it; and a URDF's geometry chosen."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh
from helpers import assert_close

from planner.errors import InputError
from planner.geometry.solid import load_object
from planner.specs import inputs
from planner.specs.objects import resolve_spec

#: [m] the box every URDF here is made of: off-centre centres of mass stay inside it.
SIZE = (0.04, 0.06, 0.1)


def box_urdf(folder: Path, inertial: str = "", visual: str = "", name: str = "box") -> Path:
    path = folder / f"{name}.urdf"
    path.write_text(f"""<robot name="{name}"><link name="base">{inertial}
  <collision><geometry><box size="{' '.join(map(str, SIZE))}"/></geometry></collision>{visual}</link></robot>""")
    return path


def inertial(xyz: str, mass: float = 0.3, diag: tuple[float, float, float] = (1.0, 1.0, 1.0)) -> str:
    ixx, iyy, izz = diag
    return (f'<inertial><origin xyz="{xyz}"/><mass value="{mass}"/>'
            f'<inertia ixx="{ixx}" iyy="{iyy}" izz="{izz}" ixy="0" ixz="0" iyz="0"/></inertial>')


def test_a_declared_origin_is_the_prepared_objects_centre_of_mass_scaled_with_the_object(tmp_path: Path) -> None:
    urdf = box_urdf(tmp_path, inertial("0.01 -0.02 0.03"))
    obj = load_object(str(urdf))
    assert_close(obj.com, [0.01, -0.02, 0.03])
    assert obj.spec.com_from == "box.urdf <inertial><origin>"
    assert obj.torque_scale == pytest.approx(np.linalg.norm(np.array(SIZE) / 2 + [0.01, 0.02, 0.03]))
    assert_close(load_object(str(urdf), scale=0.5).com, [0.005, -0.01, 0.015])  # the whole object scaled
    assert_close(load_object(str(box_urdf(tmp_path, inertial("0 0 0"), name="zero"))).com, np.zeros(3))


def test_a_plausible_urdf_inertia_is_used_for_the_mass_given_and_the_scale(tmp_path: Path) -> None:
    own = (2e-4, 1.5e-4, 1e-4)  # [kg m^2] for 0.3 kg: a real body's of this size
    urdf = box_urdf(tmp_path, inertial("0 0 0.01", diag=own))
    assert_close(load_object(str(urdf)).inertia, np.diag(own))
    assert_close(load_object(str(urdf), mass=0.6).inertia, 2 * np.diag(own))
    assert_close(load_object(str(urdf), scale=2.0).inertia, 4 * np.diag(own))


def test_a_placeholder_inertia_keeps_the_meshs(tmp_path: Path) -> None:
    mesh = trimesh.creation.box(extents=SIZE)
    mesh.density = 0.3 / mesh.volume
    assert_close(load_object(str(box_urdf(tmp_path, inertial("0 0 0.01")))).inertia, mesh.moment_inertia)


def test_a_sidecar_gives_a_meshs_com_and_replaces_a_urdfs(tmp_path: Path) -> None:
    mesh = tmp_path / "brick.obj"
    trimesh.creation.box(extents=SIZE).export(mesh)
    mesh.with_suffix(".toml").write_text("com = [0.0, 0.01, -0.02]\n")
    obj = load_object(str(mesh))
    assert_close(obj.com, [0.0, 0.01, -0.02])
    assert obj.spec.com_from == "brick.toml"
    urdf = box_urdf(tmp_path, inertial("0.01 0 0"))
    urdf.with_suffix(".toml").write_text("com = [0, 0, 0.02]\n")
    assert resolve_spec(str(urdf)).com == (0.0, 0.0, 0.02)
    assert resolve_spec(str(urdf), com="0,0,0").com == (0.0, 0.0, 0.0)  # the run's (a manifest's column) first


def test_a_manifest_column_gives_the_com(tmp_path: Path) -> None:
    trimesh.creation.box(extents=SIZE).export(tmp_path / "brick.obj")
    (tmp_path / "m.txt").write_text("brick.obj com=0.01,0,0.02\n")
    (ref,) = inputs.expand([f"@{tmp_path / 'm.txt'}"])
    assert ref.physical.com == (0.01, 0.0, 0.02)
    (tmp_path / "m.txt").write_text("brick.obj com=0.01,0\n")
    with pytest.raises(InputError, match=r"m.txt:1: com must be three numbers \[m\], x, y, z in the object frame"):
        inputs.expand([f"@{tmp_path / 'm.txt'}"])


def test_the_visual_geometry_is_chosen_and_refused_where_it_cannot_be(tmp_path: Path) -> None:
    visual = '<visual><geometry><box size="0.02 0.02 0.02"/></geometry></visual>'
    urdf = box_urdf(tmp_path, visual=visual)
    assert load_object(str(urdf)).volume == pytest.approx(np.prod(SIZE))
    chosen = load_object(str(urdf), geometry="visual")
    assert chosen.spec.geometry == "visual" and chosen.volume == pytest.approx(0.02 ** 3)
    with pytest.raises(InputError, match="geometry visual is given and it has no <visual> element"):
        resolve_spec(str(box_urdf(tmp_path, name="plain")), geometry="visual")
    with pytest.raises(InputError, match="geometry visual chooses a URDF file's elements; mug is a registry"):
        resolve_spec("mug", geometry="visual")


def test_a_template_origin_far_from_the_meshs_centre_is_said(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """mug.urdf's case: origins at the link origin, the shape 5 cm above it: the mesh's centre is planned on, and
    one line says so (PyBullet would take the origin); a centred one is not said."""
    from planner import prepare
    from planner.geometry.shapes import urdf_solid
    from planner.specs.urdf_objects import read_urdf_object

    raised = tmp_path / "raised.urdf"
    raised.write_text(f"""<robot name="raised"><link name="base">{inertial("0 0 0")}
  <collision><origin xyz="0 0 0.05"/><geometry><box size="{' '.join(map(str, SIZE))}"/></geometry></collision>
  </link></robot>""")
    with caplog.at_level("INFO", logger=prepare.LOGGER):
        urdf_solid(read_urdf_object(raised))
        urdf_solid(read_urdf_object(box_urdf(tmp_path, inertial("0 0 0"))))
    said = [r.getMessage() for r in caplog.records if "read as a template's" in r.getMessage()]
    assert len(said) == 1 and said[0].startswith(f"{raised}: its <inertial> origins lie at their link origins "
                                                 "([0, 0, 0] m), read as a template's, not a centre of mass: its "
                                                 "mesh's, 50 mm away, is planned on")


@pytest.mark.parametrize("xyz", ["nan 0 0", "0 0 inf"])
@pytest.mark.filterwarnings("error")  # refused in its own words, not after numpy's warnings of trimesh's product
def test_a_urdf_origin_that_is_no_number_is_refused_naming_the_file(tmp_path: Path, xyz: str) -> None:
    """An <inertial><origin xyz> of nan or inf (alone: no template's zero either) is refused in one line naming the
    file and its <inertial> (not a sidecar's form of a value the user never gave)."""
    urdf = box_urdf(tmp_path, inertial(xyz, diag=(1e-4, 1e-4, 1e-4)))
    with pytest.raises(InputError, match=r"box\.urdf: its <inertial> .*no finite centre of mass") as exc:
        resolve_spec(str(urdf))
    assert "\n" not in str(exc.value)
    urdf.with_suffix(".toml").write_text("com = [0, 0, 0.01]\n")  # a sidecar's replaces it
    assert_close(load_object(str(urdf)).com, [0, 0, 0.01])


@pytest.mark.parametrize("scale, urdf_z, side_z", [(1.1, "0.01", 0.011), (0.1, "0.2", 0.02)])
def test_under_scale_a_sidecar_com_equal_to_the_urdfs_scaled_replaces_nothing(
        tmp_path: Path, caplog: pytest.LogCaptureFixture, scale: float, urdf_z: str, side_z: float) -> None:
    """0.01 * 1.1 is 0.011000000000000001: the URDF's own centre times --scale is the sidecar's to round-off, and
    nothing is said to replace it (not "com [0, 0, 0.011] from box.toml replaces box.urdf's com [0, 0, 0.011]")."""
    from planner import prepare
    from planner.api.givers import note_overridden
    from planner.specs.physical import NO_PHYSICAL

    urdf = box_urdf(tmp_path, inertial(f"0 0 {urdf_z}"))
    urdf.with_suffix(".toml").write_text(f"com = [0, 0, {side_z}]\n")
    assert float(urdf_z) * scale != side_z  # the case: equal only to round-off
    with caplog.at_level("INFO", logger=prepare.LOGGER):
        note_overridden(str(urdf), resolve_spec(str(urdf), scale=scale), NO_PHYSICAL)
    assert not [r.getMessage() for r in caplog.records if "replaces" in r.getMessage()]
    urdf.with_suffix(".toml").write_text(f"com = [0, 0, {side_z * 1.5}]\n")  # a centre that is another one is said
    with caplog.at_level("INFO", logger=prepare.LOGGER):
        note_overridden(str(urdf), resolve_spec(str(urdf), scale=scale), NO_PHYSICAL)
    assert [r.getMessage() for r in caplog.records if "from box.toml replaces box.urdf's com" in r.getMessage()]
