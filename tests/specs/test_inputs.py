"""Object arguments: names, folders, globs, manifests, builtin:..."""

from __future__ import annotations

from pathlib import Path

import pytest
import trimesh

from planner.errors import InputError
from planner.specs import inputs
from planner.specs.objects import resolve_spec


def test_inputs_expand_folders_globs_manifests_and_builtins(tmp_path: Path) -> None:
    for sub in ("a", "b"):
        (tmp_path / sub).mkdir()
        trimesh.creation.box(extents=[0.03, 0.03, 0.03]).export(tmp_path / sub / "model.obj")
    (tmp_path / "manifest.txt").write_text("# objects\nbox\na/model.obj 0.5\n\nrandom_004\n")
    by_folder = inputs.expand([str(tmp_path)])
    assert sorted(r.name for r in by_folder) == ["a/model", "b/model"]
    assert len(inputs.expand([str(tmp_path / "*" / "*.obj")])) == 2
    manifest = inputs.expand([f"@{tmp_path / 'manifest.txt'}"])
    assert [r.source.endswith("model.obj") for r in manifest] == [False, True, False]
    assert manifest[1].scale == 0.5
    assert [r.name for r in inputs.expand(["builtin:random:3"])] == ["random_000", "random_001", "random_002"]
    assert [r.name for r in inputs.expand(["builtin:random:5-7"])] == ["random_005", "random_006", "random_007"]
    assert {"mug", "box", "sphere"} <= {r.name for r in inputs.expand(["builtin:all"])}
    assert len(inputs.expand(["builtin:random"])) == 1000
    assert len(inputs.expand(["box", "box"])) == 1


@pytest.mark.parametrize("arg, message", [("builtin:random:5-2000", "range must lie within 0-999"),
                                          ("builtin:random:2000", "a count of 2000 is more than the 1000 random"),
                                          ("builtin:random:0", "a count of 0 names no objects; give a count of 1"),
                                          ("builtin:random:7-3", "the first, 7, comes after the last, 3; write "
                                                                 "builtin:random:3-7"),
                                          ("builtin:random:x", "use builtin:random"),
                                          ("@nowhere.txt", "manifest not found")])
def test_bad_arguments(arg: str, message: str) -> None:
    with pytest.raises(InputError, match=message):
        inputs.expand([arg])


def test_files_differing_only_in_suffix_keep_it_in_their_names(tmp_path: Path) -> None:
    box = trimesh.creation.box(extents=[0.03, 0.03, 0.03])
    for name in ("part.obj", "part.stl", "other.obj"):
        box.export(tmp_path / name)
    (tmp_path / "deeper").mkdir()
    box.export(tmp_path / "deeper" / "part.obj")
    names = sorted(r.name for r in inputs.expand([str(tmp_path)]))
    assert names == ["deeper/part.obj", "other", f"{tmp_path.name}/part.obj", f"{tmp_path.name}/part.stl"]
    assert not any(n.startswith("/") for n in names)
    assert sorted(r.name for r in inputs.expand([str(tmp_path / "part.obj"), str(tmp_path / "other.obj")])) == [
        "other", "part"]  # no shared stem: the stems alone


def test_manifest_paths_with_blanks_and_hashes_go_in_quotes(tmp_path: Path) -> None:
    folder = tmp_path / "my meshes"
    folder.mkdir()
    trimesh.creation.box(extents=[0.03, 0.03, 0.03]).export(folder / "box #2.obj")
    manifest = tmp_path / "list.txt"
    trimesh.creation.box(extents=[0.03, 0.03, 0.03]).export(tmp_path / "bob's.obj")
    manifest.write_text('"my meshes/box #2.obj" mass=0.3  # a comment\nbob\'s.obj 0.5\n')
    refs = inputs.expand([f"@{manifest}"])
    assert [Path(r.source).name for r in refs] == ["box #2.obj", "bob's.obj"]
    assert refs[0].physical.mass == 0.3 and refs[1].scale == 0.5
    manifest.write_text('"my meshes/box #2.obj mass=0.3\n')
    with pytest.raises(InputError, match=r"list.txt:1: No closing quotation"):
        inputs.expand([f"@{manifest}"])
    manifest.write_text("box\nmissing.obj mass=0.3\n")
    with pytest.raises(InputError, match=r"list.txt:2: .*missing.obj: file not found"):
        inputs.expand([f"@{manifest}"])


def test_a_path_with_an_unquoted_blank_is_told_to_go_in_quotes(tmp_path: Path) -> None:
    """`my\\ objs/rod.stl density=800` (a shell's escape) said only "scale 'objs/rod.stl' is not a number"."""
    manifest = tmp_path / "list.txt"
    manifest.write_text("my\\ objs/rod.stl density=800\n")
    with pytest.raises(InputError, match=r"list.txt:1: scale 'objs/rod.stl' is not a number \(a path with blanks "
                                         r"goes in double quotes: \"my objs/rod.stl\"; a backslash is kept"):
        inputs.expand([f"@{manifest}"])


def test_one_file_given_two_ways_is_one_object(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    box = trimesh.creation.box(extents=[0.03, 0.03, 0.03])
    (tmp_path / "m" / "sub").mkdir(parents=True)
    box.export(tmp_path / "m" / "a.obj")
    box.export(tmp_path / "m" / "sub" / "a.obj")
    monkeypatch.chdir(tmp_path)
    refs = inputs.expand(["m/a.obj", "./m/a.obj", "m/sub/a.obj"])
    assert sorted({r.name for r in refs}) == ["m/a", "sub/a"]


def test_an_empty_manifest_name_names_its_line(tmp_path: Path) -> None:
    manifest = tmp_path / "list.txt"
    manifest.write_text('box\n"" 0.5\n')
    with pytest.raises(InputError, match=r"list.txt:2: expected .* \(an empty object\)"):
        inputs.expand([f"@{manifest}"])


def test_only_files_sharing_a_stem_get_folders_in_their_names(tmp_path: Path) -> None:
    box = trimesh.creation.box(extents=[0.03, 0.03, 0.03])
    for rel in ("cube.obj", "a/part.obj", "b/part.obj", "a/deep/x/bolt.obj", "b/deep/x/bolt.obj", "part.obj.stl"):
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        box.export(tmp_path / rel)
    names = sorted(r.name for r in inputs.expand([str(tmp_path)]))
    assert names == ["a/deep/x/bolt", "a/part", "b/deep/x/bolt", "b/part", "cube", "part.obj"]


def test_a_folder_named_like_a_builtin_is_a_folder_and_builtin_names_the_builtin(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "box").mkdir()
    monkeypatch.chdir(tmp_path)
    with pytest.raises(InputError, match="folder holds no mesh or URDF files .*; for the built-in object of that name "
                                         "write builtin:box"):
        inputs.expand(["box"])
    assert [r.name for r in inputs.expand(["builtin:box"])] == ["box"]
    assert resolve_spec(inputs.expand(["builtin:box"])[0].source).kind == "box"  # the primitive, not the folder
    with pytest.raises(InputError, match="no built-in object of that name"):
        inputs.expand(["builtin:boxx"])
    assert [r.name for r in inputs.expand(["builtin:random_003"])] == ["random_003"]


@pytest.mark.parametrize("arg", ["builtin:mug", "builtin:random:3-3", "builtin:random_003", "builtin:all"])
def test_every_builtin_spelling_takes_the_scale(arg: str) -> None:
    assert {r.scale for r in inputs.expand([arg], scale=0.5)} == {0.5}


@pytest.mark.parametrize("text, message", [
    ("box\nduck.dae 0.5\n", r"m.txt:2: .*duck.dae: unsupported mesh type '.dae'; use one of .obj.*or a URDF"),
    ("sphere\nbox 2\n", r"m.txt:2: object 'box': the row's scale applies to meshes only; box is a primitive"),
    ("\ufeffbox\nmugg\n", r"m.txt:2: unknown object 'mugg'"),  # and the BOM is not part of line 1's 'box'
])
def test_a_manifest_rows_error_names_its_line(tmp_path: Path, text: str, message: str) -> None:
    """These three named no line (a row of an unread type failed at loading;
    a byte-order mark made line 1 the unknown object '\\ufeffbox')."""
    (tmp_path / "duck.urdf").write_text("<robot name='duck'/>")
    (tmp_path / "m.txt").write_text(text, encoding="utf-8")
    with pytest.raises(InputError, match=message):
        inputs.expand([f"@{tmp_path / 'm.txt'}"])


def test_a_manifest_row_of_a_primitive_under_the_runs_scale_names_its_line_and_the_flag(tmp_path: Path) -> None:
    (tmp_path / "m.txt").write_text("\ufeffbox\n", encoding="utf-8")
    with pytest.raises(InputError, match=r"m.txt:1: object 'box': --scale applies to meshes only"):
        inputs.expand([f"@{tmp_path / 'm.txt'}"], scale=2.0)
    assert [r.name for r in inputs.expand([f"@{tmp_path / 'm.txt'}"])] == ["box"]


def test_a_folder_walk_skips_hidden_files_and_macos_resource_forks(tmp_path: Path) -> None:
    """A folder unzipped from a macOS zip holds ``._mug.obj`` and ``__MACOSX/._can.stl`` (resource forks, not
    meshes): each failed its unit ('mesh has no triangles') and the run exited 2, on every rerun."""
    folder = tmp_path / ".scans"  # a hidden folder given itself is read
    (folder / "__MACOSX").mkdir(parents=True)
    (folder / ".git").mkdir()
    trimesh.creation.box(extents=[0.03, 0.03, 0.03]).export(folder / "mug.obj")
    for junk in ("._mug.obj", "__MACOSX/._can.stl", ".git/old.obj"):
        (folder / junk).write_bytes(b"\x00\x05\x16\x07\x00\x02\x00\x00Mac OS X        " + bytes(100))
    assert [r.name for r in inputs.expand([str(folder)])] == ["mug"]


def test_a_manifest_written_on_windows_is_read_or_refused_naming_its_line(tmp_path: Path) -> None:
    """Windows PowerShell's `>` and Notepad's 'Unicode' write UTF-16 (a byte-order mark first): 'internal error:
    UnicodeDecodeError', exit 1; so did a Latin-1 name. A backslashed path said 'file not found' alone."""
    trimesh.creation.box(extents=[0.03, 0.03, 0.03]).export(tmp_path / "can.stl")
    (tmp_path / "wide.txt").write_text("# mine\r\ncan.stl mass=0.3\r\n", encoding="utf-16")
    (ref,) = inputs.expand([f"@{tmp_path / 'wide.txt'}"])
    assert (Path(ref.source).name, ref.physical.mass) == ("can.stl", 0.3)
    (tmp_path / "latin.txt").write_bytes(b"can.stl\nc\xe4n.stl\n")
    with pytest.raises(InputError, match=r"latin.txt:2: not UTF-8 text \(byte 0xe4\): save the manifest as UTF-8"):
        inputs.expand([f"@{tmp_path / 'latin.txt'}"])
    (tmp_path / "win.txt").write_text("meshes\\can.stl\n")
    with pytest.raises(InputError, match=r"win.txt:1: .*meshes\\can.stl: file not found \(a Windows path\? write / "):
        inputs.expand([f"@{tmp_path / 'win.txt'}"])


def test_a_manifest_line_naming_a_folder_or_a_glob_says_so(tmp_path: Path) -> None:
    """'sub' (a folder beside the manifest) said '/.../sub: file not found' without the line, or, run from
    another folder, 'unknown object'; 'sub/*.stl' said 'file not found'. A built-in's name stays the built-in."""
    (tmp_path / "sub").mkdir()
    (tmp_path / "mug").mkdir()
    trimesh.creation.box(extents=[0.03, 0.03, 0.03]).export(tmp_path / "sub" / "can.stl")
    trimesh.creation.box(extents=[0.03, 0.03, 0.03]).export(tmp_path / "box [2].stl")
    for line, what in (("sub", "folder"), ("sub/*.stl", "glob")):
        (tmp_path / "m.txt").write_text(f"mug\n{line} mass=0.1\n")
        with pytest.raises(InputError, match=rf"m.txt:2: sub.* is a {what}: a manifest's line names one object; give "
                                             rf"it on the command line \(`grasp generate '?{tmp_path}/sub"):
            inputs.expand([f"@{tmp_path / 'm.txt'}"])
    (tmp_path / "m.txt").write_text('mug\n"box [2].stl"\n')
    assert [r.name for r in inputs.expand([f"@{tmp_path / 'm.txt'}"])] == ["mug", "box [2]"]


@pytest.mark.parametrize("folder", ["cups", "bob's cups"])
def test_the_command_a_manifests_folder_line_gives_runs_as_pasted(tmp_path: Path, folder: str) -> None:
    """"(grasp generate '/x/bob's cups')": the folder in quotes of its own, an apostrophe in it ended them (and
    a folder that needs none was quoted all the same)."""
    import re
    import shlex

    (tmp_path / folder).mkdir()
    (tmp_path / "m.txt").write_text(f'"{folder}"\n')
    with pytest.raises(InputError) as info:
        inputs.expand([f"@{tmp_path / 'm.txt'}"])
    [command] = re.findall(r"`(grasp [^`]*)`", str(info.value))
    assert shlex.split(command) == ["grasp", "generate", str(tmp_path / folder)], command
    assert ("'" in command) == (" " in folder), command
