"""The prepared object: known mass properties, built-ins load as closed solids."""

import math
from pathlib import Path

import numpy as np
import pytest
from helpers import assert_close

from planner.geometry.mesh import union_of_bodies
from planner.geometry.solid import load_object


def test_sphere_known_answers() -> None:
    o = load_object("sphere")
    r = o.spec.dims[0]
    assert_close(o.com, [0, 0, 0], 1e-9)
    assert o.torque_scale == pytest.approx(r, rel=1e-6)
    # icosphere volume is slightly under the sphere's
    assert o.volume == pytest.approx(4 / 3 * math.pi * r**3, rel=0.02)
    assert o.density == pytest.approx(o.mass / o.volume)
    # radius of gyration from the mean principal moment, k^2 = trace(I) / (3 m):
    # for a solid sphere (I = 2/5 m r^2 per axis) k = sqrt(2/5) r
    assert o.gyration_radius == pytest.approx(math.sqrt(0.4) * r, rel=0.02)


def test_box_torque_scale_is_half_diagonal() -> None:
    o = load_object("box")
    assert o.torque_scale == pytest.approx(0.5 * np.linalg.norm(o.spec.dims), rel=1e-9)


@pytest.mark.parametrize("name", ["mug", "duck", "teddy", "bunny", "box", "cylinder", "sphere", "random_007",
                                  "random_037"])  # 53 V-HACD pieces, some sharing edges
def test_builtins_load_as_closed_solids_of_hand_size(name: str) -> None:
    o = load_object(name)
    assert o.mesh.is_watertight and o.volume > 0
    assert 0.02 < max(o.mesh.extents) < 0.2
    assert np.all(np.isfinite(o.inertia))


def test_mug_keeps_its_handle_and_cavity() -> None:
    o = load_object("mug")
    # the cavity: a point on the axis inside the cup is outside the solid
    assert not o.mesh.contains([[0.0, 0.0, 0.06]])[0]
    # the handle: a solid piece beyond the cup's radius
    assert o.mesh.bounds[1][1] > 0.07




def test_scale_multiplies_builtin_mesh_scale() -> None:
    plain, half = load_object("duck"), load_object("duck", scale=0.5)
    assert_close(half.mesh.extents, plain.mesh.extents * 0.5, 1e-9)


def test_a_cached_mesh_keeps_the_path_it_was_asked_for(tmp_path: Path) -> None:
    """The cache is keyed by content: the same bytes at two paths are one
    entry, but each object names its own file (the other may be gone)."""
    import trimesh

    first, second = tmp_path / "a" / "cube.obj", tmp_path / "b" / "cube.obj"
    for path in (first, second):
        path.parent.mkdir()
        trimesh.creation.box(extents=[0.04, 0.05, 0.06]).export(path)
    assert load_object(str(first)).source_file == str(first)
    assert load_object(str(second)).source_file == str(second)


def test_overlapping_bodies_count_their_shared_volume_once(tmp_path: Path) -> None:
    """Two 4 x 4 x 8 cm boxes 2 cm apart along z, in one file: the object is
    their union (4 x 4 x 10 cm), its mass from a density and its centre of
    mass the union's, the same when read again from the cache; bodies
    whose boxes meet but not their solids keep their sum."""
    import trimesh

    a = trimesh.creation.box(extents=[0.04, 0.04, 0.08])
    b = a.copy()
    b.apply_translation([0.0, 0.0, 0.02])
    path = tmp_path / "two.obj"
    trimesh.util.concatenate([a, b]).export(path)
    for _ in range(2):  # built, then from the cache
        o = load_object(str(path), density=500.0)
        # manifold3d's boolean rounds coordinates to float32: ~1e-9 m here
        assert o.volume == pytest.approx(0.04 * 0.04 * 0.10, rel=1e-6)
        assert o.mass == pytest.approx(500.0 * 0.04 * 0.04 * 0.10, rel=1e-6)
        assert_close(o.com, [0.0, 0.0, 0.01], 1e-8)
        assert o.inertia[0, 0] == pytest.approx(o.mass * (0.04**2 + 0.10**2) / 12, rel=1e-6)
        assert len(o.mesh.split(only_watertight=False)) == 2  # the surface planned on is the file's
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.019)
    ball.apply_translation([0.035, 0.035, 0.0])  # its box meets the box's, the solids 2 mm apart
    apart = tmp_path / "apart.obj"
    trimesh.util.concatenate([a, ball]).export(apart)
    o = load_object(str(apart))
    assert union_of_bodies(o.mesh, "apart") is None
    assert o.volume == pytest.approx(a.volume + ball.volume, rel=1e-6)  # OBJ keeps ~7 digits


def test_overlapping_bodies_without_manifold3d_are_a_one_line_error(monkeypatch: pytest.MonkeyPatch) -> None:
    import sys

    import trimesh

    from planner.errors import MeshError

    a = trimesh.creation.box(extents=[0.04, 0.04, 0.08])
    b = a.copy()
    b.apply_translation([0.0, 0.0, 0.02])
    monkeypatch.setitem(sys.modules, "manifold3d", None)  # as if not installed: nothing is cached
    with pytest.raises(MeshError, match="needs manifold3d"):
        union_of_bodies(trimesh.util.concatenate([a, b]), "two")


def test_a_gltf_is_read_again_when_its_buffer_file_changes(tmp_path: Path) -> None:
    """A .gltf keeps its geometry in the files its buffers name: the object cache is keyed by them too
    (it was keyed by the .gltf's own bytes, which stay the same when only the buffer is edited)."""
    import trimesh

    folder = tmp_path / "scan"
    folder.mkdir()
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.03)
    pinched = ball.copy()
    waist = np.abs(ball.vertices[:, 2]) < 0.01
    pinched.vertices[waist, :2] *= 0.6
    for shape in (ball, pinched):
        files = shape.export(file_type="gltf")  # model.gltf and the buffers it names
        for name, data in files.items():
            if name.endswith(".bin") or shape is ball:  # the .gltf's bounds keep the ball's: only buffers change
                (folder / name).write_bytes(data)
        volume = load_object(str(folder / "model.gltf")).volume
        assert volume == pytest.approx(shape.volume, rel=1e-6)
    assert pinched.volume < 0.9 * ball.volume


def test_gltf_buffer_names_as_written_and_decoded_and_a_file_that_is_not_gltf(tmp_path: Path) -> None:
    """trimesh opens a buffer's URI as written (`lit%20name.bin`); the key read only the decoded name, so an
    edit of that file went unseen; `"buffers": 5` was an internal error."""
    from planner.specs.object_files import gltf_buffers

    gltf = tmp_path / "m.gltf"
    gltf.write_text('{"buffers": [{"uri": "lit%20name.bin"}, {"uri": "data:application/octet-stream;base64,AA=="},'
                    ' {"uri": "plain.bin"}]}')
    assert gltf_buffers(gltf) == [tmp_path / "lit%20name.bin", tmp_path / "lit name.bin", tmp_path / "plain.bin"]
    gltf.write_text('{"buffers": 5}')
    assert gltf_buffers(gltf) == []
