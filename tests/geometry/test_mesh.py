"""Loading, checking and repairing meshes: refusals say what to fix."""

from pathlib import Path

import numpy as np
import pytest
import trimesh
from helpers import assert_close
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

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


def test_a_mesh_too_large_in_metres_is_told_its_size_in_other_units() -> None:
    """A can exported in inches (US CAD's default), 4.72 units tall, was told 'millimetres --scale 0.001,
    centimetres --scale 0.01': the first plans a 4.7 mm can, the second a 4.7 cm one; not inches."""
    can = trimesh.creation.cylinder(radius=1.38, height=4.72)
    with pytest.raises(MeshError, match=r"can: object is 4.72 m across, larger than any hand can grasp; if the mesh is "
                                        r"in millimetres pass --scale 0.001 \(0.0047 m across\), in centimetres "
                                        r"--scale 0.01 \(0.047 m across\), in inches --scale 0.0254 \(0.12 m across\)"):
        meshes.checked_solid(can, "can")


def test_missing_and_empty_files(tmp_path: Path) -> None:
    with pytest.raises(MeshError, match="not found"):
        meshes.load_mesh_file(tmp_path / "nope.obj")
    (tmp_path / "empty.obj").write_text("")
    with pytest.raises(MeshError, match="empty"):
        meshes.load_mesh_file(tmp_path / "empty.obj")
    (tmp_path / "junk.stl").write_bytes(b"\x00garbage" * 3)
    with pytest.raises(MeshError):
        meshes.load_mesh_file(tmp_path / "junk.stl")


def test_a_ply_without_a_coordinate_says_which_is_missing(tmp_path: Path) -> None:
    """A PLY header without its y property said only "cannot parse mesh: 'y'" (trimesh's KeyError)."""
    path = tmp_path / "bad.ply"
    path.write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nend_header\n1\n2\n3\n")
    with pytest.raises(MeshError, match=r"cannot parse mesh: 'y' is missing \(re-export it"):
        meshes.load_mesh_file(path)


def test_a_point_cloud_and_a_urdf_are_refused_saying_what_to_give(tmp_path: Path) -> None:
    """A scanner's PLY of points alone said 'mesh has no triangles', as a text file did; a URDF given as the
    object said its type is unsupported, without what to give instead."""
    trimesh.PointCloud(trimesh.creation.icosphere(radius=0.03).vertices).export(tmp_path / "scan.ply")
    with pytest.raises(MeshError, match=r"scan.ply: a point cloud of 642 points, no triangles: make a surface"):
        meshes.load_mesh_file(tmp_path / "scan.ply")
    trimesh.Scene(trimesh.PointCloud(trimesh.creation.icosphere(radius=0.03).vertices)).export(tmp_path / "scan.glb")
    with pytest.raises(MeshError, match=r"scan.glb: a point cloud of 642 points, no triangles"):
        meshes.load_mesh_file(tmp_path / "scan.glb")
    (tmp_path / "duck.urdf").write_text("<robot name='duck'/>")
    with pytest.raises(MeshError, match=r"unsupported mesh type '.urdf'.*a URDF describes an object, not a mesh: "
                                        r"give it as the object"):
        meshes.load_mesh_file(tmp_path / "duck.urdf")


def test_a_gltf_without_its_buffer_or_with_compressed_geometry_says_what_to_do(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A .gltf copied without its .bin said 'cannot parse mesh: gltf_buffer_0.bin'; Draco-compressed geometry,
    which trimesh decodes only with DracoPy (not installed here), said 'cannot parse mesh: 'POSITION'' (a .glb:
    'every triangle is degenerate', trimesh's placeholder zeros), each after trimesh's warnings."""
    import importlib.util
    import json

    files = trimesh.creation.box(extents=[0.03, 0.04, 0.05]).export(file_type="gltf")
    for name, data in files.items():
        (tmp_path / name).write_bytes(data)
    assert meshes.load_mesh_file(tmp_path / "model.gltf").volume == pytest.approx(6e-5)
    buffer = "gltf_buffer_0.bin"
    (tmp_path / buffer).unlink()
    with pytest.raises(MeshError, match=f"model.gltf: cannot read it: the buffer file holding its geometry, {buffer}, "
                                        "is not beside it: copy it with the .gltf, or export a .glb"):
        meshes.load_mesh_file(tmp_path / "model.gltf")
    (tmp_path / buffer).write_bytes(files[buffer])
    draco = json.loads(files["model.gltf"])
    draco["extensionsUsed"] = draco["extensionsRequired"] = ["KHR_draco_mesh_compression"]
    for primitive in draco["meshes"][0]["primitives"]:  # the geometry is in the extension's buffer view
        primitive["extensions"] = {"KHR_draco_mesh_compression": {"bufferView": 0, "attributes": {"POSITION": 0}}}
        primitive["attributes"] = {}
    (tmp_path / "draco.gltf").write_text(json.dumps(draco))
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "DracoPy" else real(name, *a))
    with pytest.raises(MeshError, match=r"draco.gltf: cannot read it: its geometry is Draco-compressed "
                                        r"\(KHR_draco_mesh_compression\): pip install DracoPy"):
        meshes.load_mesh_file(tmp_path / "draco.gltf")


def test_a_gltf_of_normalized_integer_positions_is_refused(tmp_path: Path) -> None:
    """KHR_mesh_quantization's normalized int16 positions (a 5 cm box stored as 0..32767 with a node scale of
    0.04): trimesh ignores 'normalized', so the box read 2.62 km across and was refused as 'in millimetres? pass
    --scale 0.001', which would plan a 2.6 m box."""
    import base64
    import json

    box = trimesh.creation.box(extents=[0.05, 0.06, 0.08])
    ints = np.round(box.vertices / 0.04 * 32767).astype(np.int16)
    indices = box.faces.astype(np.uint16).tobytes()
    positions = np.hstack([ints, np.zeros((len(ints), 1), np.int16)]).tobytes()  # 8-byte stride
    data = indices + positions
    (tmp_path / "q.gltf").write_text(json.dumps({
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "scale": [0.04] * 3}],
        "extensionsUsed": ["KHR_mesh_quantization"], "extensionsRequired": ["KHR_mesh_quantization"],
        "buffers": [{"byteLength": len(data), "uri": "data:application/octet-stream;base64," +
                     base64.b64encode(data).decode()}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": len(indices)},
                        {"buffer": 0, "byteOffset": len(indices), "byteLength": len(positions), "byteStride": 8}],
        "accessors": [{"bufferView": 0, "componentType": 5123, "type": "SCALAR", "count": box.faces.size},
                      {"bufferView": 1, "componentType": 5122, "type": "VEC3", "count": len(ints), "normalized": True,
                       "min": ints.min(axis=0).tolist(), "max": ints.max(axis=0).tolist()}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 1}, "indices": 0}]}]}))
    with pytest.raises(MeshError, match=r"q.gltf: cannot read it: its positions are quantized to normalized integers "
                                        r"\(KHR_mesh_quantization\), which trimesh reads unscaled"):
        meshes.load_mesh_file(tmp_path / "q.gltf")


def test_hash_depends_on_geometry_only() -> None:
    a = trimesh.creation.box(extents=[0.04, 0.04, 0.04])
    assert meshes.mesh_hash(a) == meshes.mesh_hash(a.copy())
    b = a.copy()
    b.apply_scale(1.01)
    assert meshes.mesh_hash(a) != meshes.mesh_hash(b)


def test_open_mesh_is_repaired_and_nonmanifold_refused(tmp_path: Path) -> None:
    box = trimesh.creation.box(extents=[0.04, 0.04, 0.04])
    open_box = trimesh.Trimesh(box.vertices, box.faces[2:], process=False)
    assert meshes.checked_solid(open_box, "open").is_watertight
    # three triangles on one edge (a fin through a box): non-manifold, cannot be closed
    fin_v = np.vstack([box.vertices, [[0.0, 0.0, 0.1]]])
    edge = box.edges_unique[0]
    fin = trimesh.Trimesh(fin_v, np.vstack([box.faces, [[edge[0], edge[1], len(fin_v) - 1]]]), process=False)
    with pytest.raises(MeshError):
        meshes.checked_solid(fin, "fin")


def test_repeated_triangles_are_dropped() -> None:
    """An exporter's leftovers: a triangle given twice (also from another
    corner, or wound the other way) is kept once; the solid is the box."""
    box = trimesh.creation.box(extents=[0.04, 0.04, 0.08])
    again = np.vstack([box.faces, box.faces[:2], np.roll(box.faces[2:4], 1, axis=1), box.faces[4:5, ::-1]])
    solid = meshes.checked_solid(trimesh.Trimesh(box.vertices, again, process=False), "repeated")
    assert solid.is_watertight and len(solid.faces) == len(box.faces)
    assert_close(solid.volume, 0.04 * 0.04 * 0.08, 1e-12)
    assert meshes.mesh_hash(solid) == meshes.mesh_hash(meshes.checked_solid(box, "box"))


def test_bodies_touching_along_an_edge_are_kept_apart() -> None:
    """Two cubes sharing one edge: merged, that edge has four faces (not a
    solid); kept as the file's two closed bodies, they are one object."""
    a = trimesh.creation.box(extents=[0.03, 0.03, 0.03])
    b = a.copy()
    b.apply_translation([0.03, 0.03, 0.0])
    given = trimesh.util.concatenate([a, b])
    merged = given.copy()
    merged.merge_vertices()
    assert not merged.is_watertight
    solid = meshes.checked_solid(given, "two")
    assert solid.is_watertight and len(solid.split(only_watertight=False)) == 2
    assert_close(solid.volume, 2 * 0.03**3, 1e-12)
    holed = trimesh.Trimesh(given.vertices, given.faces[1:], process=False)  # a piece's small hole: closed
    assert_close(meshes.checked_solid(holed, "holed").volume, 2 * 0.03**3, 1e-12)
    fin = np.vstack([given.vertices, [[0.0, 0.0, 0.1]]])  # a fin on a piece: that piece cannot be closed
    edge = a.edges_unique[0]
    finned = trimesh.Trimesh(fin, np.vstack([given.faces, [[edge[0], edge[1], len(fin) - 1]]]), process=False)
    with pytest.raises(MeshError, match="not watertight"):
        meshes.checked_solid(finned, "finned")


def test_millions_of_faces_refused_before_work(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(meshes, "MAX_FACES", 1000)
    big = trimesh.creation.icosphere(subdivisions=4, radius=0.03)  # 5,120 faces
    path = tmp_path / "big.stl"
    big.export(path)
    with pytest.raises(MeshError, match="simplify it below 1,000"):
        meshes.load_mesh_file(path)
    monkeypatch.setattr(meshes, "MAX_FILE_BYTES", 10)
    with pytest.raises(MeshError, match="too large"):
        meshes.load_mesh_file(path)


coords = st.one_of(st.floats(min_value=-1.0, max_value=1.0, width=32),
                   st.sampled_from([float("nan"), float("inf"), -float("inf")]))


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(vertices=st.lists(st.tuples(coords, coords, coords), min_size=0, max_size=12),
       faces=st.lists(st.tuples(st.integers(0, 11), st.integers(0, 11), st.integers(0, 11)), max_size=20),
       scale=st.sampled_from([0.001, 0.05, 1.0]))
def test_fuzz_meshes_load_or_refuse_cleanly(vertices, faces, scale) -> None:  # type: ignore[no-untyped-def]
    v = np.array(vertices, float).reshape(-1, 3) * scale
    f = np.array([t for t in faces if max(t) < len(v)], int).reshape(-1, 3)
    try:
        solid = meshes.checked_solid(trimesh.Trimesh(v, f, process=False), "fuzz")
    except MeshError:
        return
    assert solid.is_watertight and solid.volume > 0 and np.all(np.isfinite(solid.vertices))


@pytest.mark.parametrize("debris, where", [
    (trimesh.Trimesh([[0.3, 0.0, 0.0], [0.301, 0.0, 0.0], [0.3, 0.001, 0.0]], [[0, 1, 2]]), "1 mm across at 0.3"),
    (trimesh.Trimesh([[0.3, 0.0, 0.0], [0.301, 0.0, 0.0], [0.301, 0.001, 0.0], [0.3, 0.001, 0.0]],
                     [[0, 1, 2], [0, 2, 3]]), "1 mm across at 0.3"),
    (trimesh.Trimesh([[-0.1, -0.1, -0.03], [0.1, -0.1, -0.03], [0.1, 0.1, -0.03], [-0.1, 0.1, -0.03]],
                     [[0, 1, 2], [0, 2, 3]]), "200 mm across at 0, 0, -0.03"),
])
def test_a_flat_body_beside_the_object_is_refused_saying_where(debris: trimesh.Trimesh, where: str) -> None:
    """A scrap triangle or quad of a scan 30 cm away, or a ground plane: the repair closed them into bodies
    of no volume, kept without a word (every epsilon cut sevenfold by the torque scale they set), or refused
    as 'not watertight'."""
    cube = trimesh.creation.box(extents=[0.05, 0.05, 0.05])
    with pytest.raises(MeshError, match="1 of its 2 bodies is flat") as refused:
        meshes.checked_solid(trimesh.util.concatenate([cube, debris]), "scan")
    assert where in str(refused.value) and "remove it in a mesh editor" in str(refused.value)
    fleck = trimesh.creation.box(extents=[0.002, 0.002, 0.002])  # a closed fleck has volume: an object's body
    fleck.apply_translation([0.3, 0.0, 0.0])
    assert meshes.checked_solid(trimesh.util.concatenate([cube, fleck]), "scan").body_count == 2


def test_a_flat_face_inside_or_on_the_object_is_left_as_it_was() -> None:
    """An internal triangle or a decal on a face loaded before the flat-body check and changes neither the
    object's reach nor its mass: still loads (the reviewer's tri_inside.obj, tri_decal_on_top.obj)."""
    cube = trimesh.creation.box(extents=[0.05, 0.05, 0.05])
    for z in (0.0, 0.025):  # inside, on the top face
        tri = trimesh.Trimesh([[0.0, 0.0, z], [0.01, 0.0, z], [0.0, 0.01, z]], [[0, 1, 2]])
        solid = meshes.checked_solid(trimesh.util.concatenate([cube, tri]), "decal")
        assert_close(solid.bounds, cube.bounds, 1e-12)


def test_a_mesh_far_from_its_frames_origin_is_said(caplog: pytest.LogCaptureFixture) -> None:
    """A CAD part exported at x = 1.2 m in its assembly's frame loaded without a word: its grasp poses and
    --object-pose are 1.2 m off its geometry. A mesh resting on its origin (a base at z = 0) is not noted."""
    import logging

    from planner import prepare

    far = trimesh.creation.box(extents=[0.05, 0.05, 0.1])
    far.apply_translation([1.2, 0.0, 0.0])
    standing = trimesh.creation.box(extents=[0.05, 0.05, 0.1])
    standing.apply_translation([0.0, 0.0, 0.05])
    with caplog.at_level(logging.INFO, logger=prepare.LOGGER):
        meshes.checked_solid(far, "part")
        meshes.checked_solid(standing, "mug")
    lines = [r.getMessage() for r in caplog.records if r.name == prepare.LOGGER]
    assert lines == ["part: its frame's origin lies 1.2 m from the mesh (a part exported in an assembly's frame?): its "
                     "grasps, exports and --object-pose are in that frame; move the mesh to the origin in a mesh "
                     "editor if that is not meant (once: cached afterwards)"]


def test_bodies_that_stand_apart_are_said_to_be_one_rigid_object(caplog: pytest.LogCaptureFixture) -> None:
    """A cube and a ball 10 cm apart in one file loaded as one rigid object without a word (its grasps on the
    ball 'lift' the cube); touching pieces (convex parts, CAD) are not noted."""
    import logging

    from planner import prepare

    cube = trimesh.creation.box(extents=[0.03, 0.03, 0.03])
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.015)
    ball.apply_translation([0.1, 0.0, 0.0])
    touching = trimesh.creation.box(extents=[0.03, 0.03, 0.03])
    touching.apply_translation([0.03, 0.0, 0.0])
    with caplog.at_level(logging.INFO, logger=prepare.LOGGER):
        meshes.checked_solid(trimesh.util.concatenate([cube, ball]), "pair")
        meshes.checked_solid(trimesh.util.concatenate([cube, touching]), "pieces")
    lines = [r.getMessage() for r in caplog.records if r.name == prepare.LOGGER]
    assert lines == ["pair: 2 of its 2 bodies stand apart from the others (their boxes meet no other's): the whole "
                     "is taken as one rigid object (a grasp of one part lifts all); split the file to plan each on "
                     "its own (once: cached afterwards)"], lines


def test_a_gltf_whose_draco_compression_is_optional_loads_from_its_plain_geometry(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """KHR_draco_mesh_compression in extensionsUsed only (not extensionsRequired): the file stores its geometry
    plain too (the extension's fallback), which trimesh reads without DracoPy; it was refused ('pip install
    DracoPy')."""
    import importlib.util
    import json

    files = trimesh.creation.box(extents=[0.03, 0.04, 0.05]).export(file_type="gltf")
    for name, data in files.items():
        (tmp_path / name).write_bytes(data)
    fallback = json.loads(files["model.gltf"])
    fallback["extensionsUsed"] = ["KHR_draco_mesh_compression"]
    for primitive in fallback["meshes"][0]["primitives"]:  # compressed, and its plain accessors kept
        primitive["extensions"] = {"KHR_draco_mesh_compression": {"bufferView": 0, "attributes": {"POSITION": 0}}}
    (tmp_path / "fallback.gltf").write_text(json.dumps(fallback))
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "DracoPy" else real(name, *a))
    assert meshes.load_mesh_file(tmp_path / "fallback.gltf").volume == pytest.approx(6e-5)
    fallback["extensionsRequired"] = ["KHR_draco_mesh_compression"]  # no fallback: refused as before
    (tmp_path / "required.gltf").write_text(json.dumps(fallback))
    with pytest.raises(MeshError, match=r"required.gltf: cannot read it: its geometry is Draco-compressed"):
        meshes.load_mesh_file(tmp_path / "required.gltf")
