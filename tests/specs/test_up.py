"""An object's up as input: the axis vocabulary, the glTF default, the sidecar
key, the manifest column and which source wins."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from planner.errors import InputError
from planner.specs import inputs
from planner.specs.objects import Physical, resolve_spec
from planner.specs.up import AXES, DEFAULT_UP, default_up, up_axis, up_vector


@pytest.fixture
def brick(tmp_path: Path) -> Path:
    path = tmp_path / "brick.obj"
    trimesh.creation.box(extents=(0.05, 0.04, 0.06)).export(path)
    return path


@pytest.mark.parametrize("given, axis", [("+y", "+y"), ("y", "+y"), (" -Z ", "-z"), ("X", "+x"), ("+z", "+z")])
def test_an_up_is_a_signed_axis_and_a_bare_axis_means_plus(given: str, axis: str) -> None:
    assert up_axis(given) == axis


@pytest.mark.parametrize("bad", ["w", "+w", "up", "", "++y", "y+", 1, None, "0,1,0"])
def test_a_bad_up_is_one_line_naming_the_field_and_where(bad: object) -> None:
    with pytest.raises(InputError) as info:
        up_axis(bad, "list.txt:3", "--up")
    text = str(info.value)
    assert text.startswith("list.txt:3: --up must be an axis") and "+x -x +y -y +z -z" in text and "\n" not in text


def test_each_axis_is_a_unit_vector_of_the_object_frame() -> None:
    vectors = np.array([up_vector(a) for a in AXES])
    assert np.array_equal(vectors, np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]]))
    assert up_vector(DEFAULT_UP).tolist() == [0.0, 0.0, 1.0]


def test_gltf_is_y_up_by_its_specification_and_every_other_file_z_up() -> None:
    assert default_up("mug.glb") == default_up("a/MUG.GLTF") == "+y"
    assert {default_up(f"m.{s}") for s in ("obj", "stl", "ply", "off")} == {"+z"}


def test_a_mesh_file_gets_its_formats_up_and_given_values_win(tmp_path: Path, brick: Path) -> None:
    glb = tmp_path / "cup.glb"
    trimesh.creation.box(extents=(0.05, 0.04, 0.06)).export(glb)
    assert resolve_spec(str(glb)).up == "+y" and resolve_spec(str(brick)).up == "+z"
    assert resolve_spec(str(glb), up="z").up == "+z" and resolve_spec(str(brick), up="-x").up == "-x"
    assert resolve_spec("mug").up == "+z" and resolve_spec("mug", up="+y").up == "+y"


def test_the_sidecar_gives_an_up_and_a_flag_beats_it(brick: Path) -> None:
    brick.with_suffix(".toml").write_text('up = "+y"\nmass = 0.1\n')
    assert resolve_spec(str(brick)).up == "+y"
    assert resolve_spec(str(brick), up="-z").up == "-z"
    brick.with_suffix(".toml").write_text('up = "sideways"\n')
    with pytest.raises(InputError, match=r"brick.toml: up must be an axis"):
        resolve_spec(str(brick))


def test_the_manifest_column_beats_the_run_and_a_bad_one_names_its_line(tmp_path: Path, brick: Path) -> None:
    (tmp_path / "list.txt").write_text("brick.obj up=+y\nbrick.obj 2 up=x\n")
    refs = inputs.expand([f"@{tmp_path / 'list.txt'}"], physical=Physical(up="-z"))
    assert [r.physical.up for r in refs] == ["+y", "+x"]
    (tmp_path / "bad.txt").write_text("brick.obj up=+q\n")
    with pytest.raises(InputError, match=r"bad.txt:1: up must be an axis"):
        inputs.expand([f"@{tmp_path / 'bad.txt'}"])


def test_physical_up_is_kept_in_canonical_form_and_over_takes_it_alone() -> None:
    assert Physical(up="Y") == Physical(up="+y")
    assert Physical(friction=0.2).over(Physical(mass=0.3, up="+x")) == Physical(mass=0.3, friction=0.2, up="+x")
    assert Physical(up="-y").over(Physical(up="+x")).up == "-y"
    assert Physical.checked({"up": "z"}, prefix="--").given() == {"up": "+z"}
