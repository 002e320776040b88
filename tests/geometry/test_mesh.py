from pathlib import Path

import numpy as np
import pytest
import trimesh
from helpers import assert_close

from planner.errors import MeshError
from planner.geometry import mesh as meshes


def write(tmp_path: Path, m: trimesh.Trimesh, name: str = "m.stl") -> Path:
    path = tmp_path / name
    m.export(path)
    return path


def test_box_loads_with_its_volume(tmp_path: Path) -> None:
    m = meshes.load_mesh_file(write(tmp_path, trimesh.creation.box(extents=[0.1, 0.05, 0.02])))
    assert m.is_watertight
    assert_close(m.volume, 0.1 * 0.05 * 0.02, 1e-12)


def test_scale_applies(tmp_path: Path) -> None:
    m = meshes.load_mesh_file(write(tmp_path, trimesh.creation.box(extents=[100, 50, 20])), scale=0.001)
    assert_close(m.extents, [0.1, 0.05, 0.02], 1e-9)


def test_open_box_is_capped_to_the_same_volume() -> None:
    box = trimesh.creation.box(extents=[0.04, 0.04, 0.04])
    top = np.flatnonzero(box.face_normals[:, 2] > 0.9)
    open_box = trimesh.Trimesh(box.vertices, np.delete(box.faces, top, axis=0), process=False)
    assert not open_box.is_watertight
    capped = meshes.cap_boundary_loops(open_box)
    assert capped.is_watertight
    assert_close(abs(capped.volume), 0.04**3, 1e-12)


def test_open_cylinder_tube_is_repaired() -> None:
    cyl = trimesh.creation.cylinder(radius=0.02, height=0.05, sections=24)
    sides = np.abs(cyl.face_normals[:, 2]) < 0.5
    tube = trimesh.Trimesh(cyl.vertices, cyl.faces[sides], process=False)
    solid = meshes.checked_solid(tube, "tube")
    assert solid.is_watertight and solid.volume > 0
    assert abs(solid.volume - cyl.volume) / cyl.volume < 1e-6


@pytest.mark.parametrize("name, build, message", [
    ("nan", lambda: trimesh.Trimesh([[0, 0, 0], [np.nan, 0, 0], [0, 1, 0]], [[0, 1, 2]], process=False), "NaN"),
    ("flat", lambda: trimesh.Trimesh([[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0], [0.1, 0.1, 0]], [[0, 1, 2], [1, 3, 2]],
                                     process=False), "volume|repaired"),
    ("huge", lambda: trimesh.creation.box(extents=[50, 40, 80]), "millimetres"),
    ("tiny", lambda: trimesh.creation.box(extents=[1e-4, 1e-4, 1e-4]), "smaller than a millimetre"),
    ("empty", lambda: trimesh.Trimesh(np.zeros((0, 3)), np.zeros((0, 3), int)), "no triangles"),
])
def test_bad_meshes_are_refused(name: str, build, message: str) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(MeshError, match=message):
        meshes.checked_solid(build(), name)


def test_missing_and_empty_files(tmp_path: Path) -> None:
    with pytest.raises(MeshError, match="not found"):
        meshes.load_mesh_file(tmp_path / "nope.obj")
    (tmp_path / "empty.obj").write_text("")
    with pytest.raises(MeshError, match="empty"):
        meshes.load_mesh_file(tmp_path / "empty.obj")
    (tmp_path / "junk.stl").write_bytes(b"\x00garbage" * 3)
    with pytest.raises(MeshError):
        meshes.load_mesh_file(tmp_path / "junk.stl")


def test_hash_depends_on_geometry_only() -> None:
    a = trimesh.creation.box(extents=[0.04, 0.04, 0.04])
    assert meshes.mesh_hash(a) == meshes.mesh_hash(a.copy())
    b = a.copy()
    b.apply_scale(1.01)
    assert meshes.mesh_hash(a) != meshes.mesh_hash(b)
