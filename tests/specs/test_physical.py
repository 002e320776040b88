"""An object's physical properties as input: checked values, the sidecar,
manifest columns, which source wins, and the density turned into a mass."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import trimesh
from helpers import NUM_TOL

from planner.errors import ConfigError, InputError
from planner.geometry.solid import load_object
from planner.specs import inputs
from planner.specs.objects import resolve_spec
from planner.specs.physical import MAX_FRICTION, Physical

BRICK = (0.05, 0.04, 0.06)  # [m]: volume 1.2e-4 m^3


@pytest.fixture
def brick(tmp_path: Path) -> Path:
    path = tmp_path / "brick.obj"
    trimesh.creation.box(extents=BRICK).export(path)
    return path


@pytest.mark.parametrize("values, needle", [
    ({"mass": -1}, "mass must be a positive number [kg], got -1"),
    ({"mass": 0}, "mass must be a positive number"),
    ({"density": float("nan")}, "density must be a positive number [kg/m^3], got nan"),
    ({"friction": 0}, "friction must be a positive number"),
    ({"friction": MAX_FRICTION * 2}, "friction must lie in (0, 3]"),
    ({"friction": "high"}, "friction must be a number [Coulomb coefficient], got 'high'"),
    ({"mass": True}, "mass must be a number"),
    ({"mass": 1, "density": 500}, "mass and density exclude each other"),
    ({"weight": 1}, "unknown field 'weight'"),
])
def test_bad_values_name_the_field_and_where(values: dict, needle: str) -> None:
    with pytest.raises(InputError) as info:
        Physical.checked(values, "list.txt:3")
    assert str(info.value).startswith("list.txt:3: ") and needle in str(info.value)


def test_cli_prefix_names_the_flag() -> None:
    with pytest.raises(InputError, match="^--mass and --density exclude each other"):
        Physical.checked({"mass": 1.0, "density": 2.0}, prefix="--")


def test_over_takes_mass_or_density_together() -> None:
    line, run = Physical(density=500.0), Physical(mass=0.3, friction=0.9)
    assert line.over(run) == Physical(density=500.0, friction=0.9)
    assert Physical(friction=0.2).over(run) == Physical(mass=0.3, friction=0.2)
    assert Physical().over(run) == run


def test_sidecar_is_read_and_explicit_values_win(brick: Path) -> None:
    brick.with_suffix(".toml").write_text("density = 500.0\nfriction = 0.8\n")
    spec = resolve_spec(str(brick))
    assert (spec.density, spec.friction) == (500.0, 0.8)
    spec = resolve_spec(str(brick), mass=0.07)
    assert (spec.mass, spec.density, spec.friction) == (0.07, None, 0.8)
    assert resolve_spec(str(brick), friction=0.3).friction == 0.3


def test_bad_sidecar_is_an_error_naming_the_file(brick: Path) -> None:
    brick.with_suffix(".toml").write_text("mass = -0.1\n")
    with pytest.raises(InputError, match=r"brick\.toml: mass must be a positive number"):
        resolve_spec(str(brick))
    brick.with_suffix(".toml").write_text("mass = 0.1\ndensity = 3.0\n")
    with pytest.raises(InputError, match=r"brick\.toml: mass and density exclude each other"):
        resolve_spec(str(brick))


def test_density_gives_mass_density_times_volume(brick: Path) -> None:
    obj = load_object(str(brick), density=500.0)
    volume = math.prod(BRICK)
    assert obj.volume == pytest.approx(volume, rel=NUM_TOL)
    assert obj.mass == pytest.approx(500.0 * volume, rel=NUM_TOL) and obj.density == 500.0
    heavy = load_object(str(brick), mass=0.5)
    assert heavy.mass == 0.5 and heavy.density == pytest.approx(0.5 / volume, rel=NUM_TOL)
    assert heavy.gyration_radius == pytest.approx(obj.gyration_radius, rel=NUM_TOL)  # a shape's, not a mass's


def test_builtins_take_the_overrides_too() -> None:
    assert resolve_spec("box", friction=0.9).friction == 0.9
    assert load_object("box", density=1000.0).mass == pytest.approx(1000.0 * load_object("box").volume)


def test_scale_zero_is_refused_like_a_negative_one(brick: Path) -> None:
    for scale in (0.0, -1.0):
        with pytest.raises(InputError, match="scale must be a positive number"):
            resolve_spec(str(brick), scale=scale)
        with pytest.raises(InputError, match="scale must be a positive number"):
            resolve_spec("box", scale=scale)


def test_scale_applies_to_random_objects_and_is_refused_for_primitives() -> None:
    assert resolve_spec("random_005", scale=2.0).scale == 2.0 * resolve_spec("random_005").scale
    assert resolve_spec("box", scale=1.0).dims == resolve_spec("box").dims
    with pytest.raises(InputError, match="--scale applies to meshes only; box is a primitive of fixed size"):
        resolve_spec("box", scale=2.0)


def test_manifest_columns(tmp_path: Path, brick: Path) -> None:
    (tmp_path / "objects.txt").write_text(
        "brick.obj 0.5 mass=0.066 friction=0.8  # scale, then columns\n"
        "box density=700\n"
        "random_004 scale=2\n")  # a primitive takes no scale: refused (test_inputs)
    refs = inputs.expand([f"@{tmp_path / 'objects.txt'}"], physical=Physical(mass=0.3, friction=0.4))
    assert [(r.scale, r.physical) for r in refs] == [
        (0.5, Physical(mass=0.066, friction=0.8)),
        (None, Physical(density=700.0, friction=0.4)),  # the line's density wins over the run's mass
        (2.0, Physical(mass=0.3, friction=0.4)),
    ]


@pytest.mark.parametrize("line, needle", [
    ("brick.obj mass=abc", "objects.txt:1: mass must be a number [kg], got 'abc'"),
    ("brick.obj mass=-2", "objects.txt:1: mass must be a positive number"),
    ("brick.obj mass=1 density=2", "objects.txt:1: mass and density exclude each other"),
    ("brick.obj friction=9", "objects.txt:1: friction must lie in"),
    ("brick.obj 0", "objects.txt:1: scale must be a positive number, got 0"),
    ("brick.obj 1 2", "objects.txt:1: a value without a name, '2', after '1' (only the scale"),
    ("brick.obj mass=1 0.5", "objects.txt:1: a value without a name, '0.5', after 'mass=1' (only the scale"),
    ("brick.obj weight=2", "objects.txt:1: unknown column 'weight' (columns: scale, mass, density, friction"),
    ("brick.obj mass=1 mass=2", "objects.txt:1: mass given twice; expected 'OBJECT [SCALE]"),
    ("brick.obj 0.5 scale=2", "objects.txt:1: scale given twice"),
])
def test_bad_manifest_columns(tmp_path: Path, brick: Path, line: str, needle: str) -> None:
    """A line's bad column said only "expected '...', got LINE", with the line re-quoted (a non-ASCII name in
    quotes the user did not write): now what is wrong in it."""
    (tmp_path / "objects.txt").write_text(line + "\n")
    with pytest.raises(InputError) as info:
        inputs.expand([f"@{tmp_path / 'objects.txt'}"])
    assert needle in str(info.value)


def test_run_values_apply_to_every_plain_argument(tmp_path: Path, brick: Path) -> None:
    run = Physical(friction=0.7)
    refs = inputs.expand(["box", str(tmp_path)], physical=run)
    assert [r.physical for r in refs] == [run, run]


def test_an_upper_case_sidecar_is_read_and_two_are_refused(brick: Path) -> None:
    """B.STL with B.TOML got the defaults without a word (a scanner writing upper-case names)."""
    brick.with_suffix(".TOML").write_text("mass = 0.066\nfriction = 0.8\n")
    spec = resolve_spec(str(brick))
    assert (spec.mass, spec.friction) == (0.066, 0.8)
    brick.with_suffix(".toml").write_text("mass = 0.07\n")
    if brick.with_suffix(".toml").samefile(brick.with_suffix(".TOML")):
        pytest.skip("a case-blind file system: brick.toml and brick.TOML are one file")
    with pytest.raises(InputError, match=r"two sidecars, brick\.TOML and brick\.toml: keep one"):
        resolve_spec(str(brick))


def test_a_mixed_case_sidecar_is_read(brick: Path) -> None:
    """B.Toml was not read (only .toml and .TOML were probed)."""
    brick.with_suffix(".Toml").write_text("mass = 0.066\nfriction = 0.8\n")
    brick.with_name("brick_other.toml").write_text("mass = 5\n")  # another stem: not this mesh's
    spec = resolve_spec(str(brick))
    assert (spec.mass, spec.friction) == (0.066, 0.8)


def test_a_sidecar_meant_for_a_mesh_but_named_otherwise_is_refused(tmp_path: Path) -> None:
    """Banana.obj + banana.toml (read on macOS and Windows, whose file systems are case-blind) and
    Kiwi.obj + Kiwi.obj.toml got the default 0.2 kg on Linux without a word."""
    folders = {name: tmp_path / name for name in ("case", "whole", "other")}
    for folder, (mesh, toml) in zip(folders.values(), [("Banana.obj", "banana.toml"), ("Kiwi.obj", "Kiwi.obj.toml"),
                                                        ("Banana.obj", "banana.toml")]):
        folder.mkdir()
        trimesh.creation.box(extents=BRICK).export(folder / mesh)
        (folder / toml).write_text("mass = 0.066\n")
    if (folders["case"] / "Banana.toml").exists():
        pytest.skip("a case-blind file system: banana.toml is Banana.obj's sidecar")
    trimesh.creation.box(extents=BRICK).export(folders["other"] / "banana.stl")  # banana.toml is banana.stl's
    with pytest.raises(InputError, match=r"Banana.obj: banana.toml beside it is not read as its sidecar \(one takes "
                                         r"the mesh's name, in the same case, with .toml in place of .obj\): rename "
                                         r"it Banana.toml"):
        [r.name for r in inputs.expand([str(folders["case"])])]
    with pytest.raises(InputError, match=r"Kiwi.obj.toml beside it is not read .* rename it Kiwi.toml"):
        resolve_spec(str(folders["whole"] / "Kiwi.obj"))
    assert resolve_spec(str(folders["other"] / "Banana.obj")).mass == pytest.approx(0.2)
    assert resolve_spec(str(folders["other"] / "banana.stl")).mass == pytest.approx(0.066)


@pytest.mark.parametrize("encoding", ["utf-8-sig", "utf-16"])
def test_a_sidecar_saved_by_a_windows_editor_is_read(brick: Path, encoding: str) -> None:
    """A UTF-8 byte-order mark (Notepad before 2019) said 'malformed TOML: Invalid statement (at line 1, column
    1)'; UTF-16 (Notepad's 'Unicode', PowerShell's >) said 'cannot read: 'utf-8' codec can't decode byte 0xff'."""
    brick.with_suffix(".toml").write_text("# Bäume\nmass = 0.066\nfriction = 0.8\n", encoding=encoding)
    spec = resolve_spec(str(brick))
    assert (spec.mass, spec.friction) == (0.066, 0.8)
    brick.with_suffix(".toml").write_text("# Bäume\nmass = 0.066\n", encoding="latin-1")
    with pytest.raises(ConfigError, match=r"brick.toml:1: not UTF-8 text \(byte 0xe4\): save the file as UTF-8"):
        resolve_spec(str(brick))


def test_one_sidecar_answering_to_two_spellings_is_read_once(brick: Path) -> None:
    """A case-blind file system (macOS, Windows) answers brick.toml and brick.TOML with one file; the listing
    that replaced the probes missed B.toml beside b.stl there. One file (here a hard link under both names) is one
    sidecar, read, not refused as two."""
    brick.with_suffix(".toml").write_text("mass = 0.066\n")
    brick.with_suffix(".TOML").hardlink_to(brick.with_suffix(".toml"))
    assert resolve_spec(str(brick)).mass == 0.066


def test_a_symlinked_mesh_is_named_and_sidecared_as_its_link(tmp_path: Path, brick: Path) -> None:
    """A mesh given through a symlink (a dataset folder of links into a content store) took the target's name
    and read the target's sidecar, never the one beside the link; by a folder, a glob and a manifest line too.
    The link's own sidecar now, the target's where the link has none; the source is the file itself."""
    store = tmp_path / "store"
    store.mkdir()
    target = store / "3f9a1c.obj"
    brick.rename(target)
    target.with_suffix(".toml").write_text("mass = 0.5\n")
    objects = tmp_path / "objects"
    objects.mkdir()
    (objects / "banana.obj").symlink_to(target)
    (objects / "banana.toml").write_text("mass = 0.066\nfriction = 0.8\n")
    (objects / "plain.obj").symlink_to(target)  # no sidecar of its own
    spec = resolve_spec(str(objects / "banana.obj"))
    assert (spec.name, spec.mass, spec.friction, spec.source) == ("banana", 0.066, 0.8, str(target.resolve()))
    plain = resolve_spec(str(objects / "plain.obj"))
    assert (plain.name, plain.mass) == ("plain", 0.5)
    (tmp_path / "list.txt").write_text("objects/banana.obj\n")
    for arg in (str(objects), str(objects / "*.obj"), f"@{tmp_path / 'list.txt'}"):
        refs = inputs.expand([arg])
        names = sorted(resolve_spec(r.source, label=r.label).name for r in refs)
        assert names == (["banana"] if arg.startswith("@") else ["banana", "plain"]), arg
        banana = next(r for r in refs if Path(r.source).name == "banana.obj")
        assert resolve_spec(banana.source, label=banana.label).mass == 0.066
