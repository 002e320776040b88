"""Every export read the way its peer reads it, from a copy of the export
folder moved to another directory (the original deleted): ACRONYM's
``load_grasps`` / ``load_mesh``, GraspGen's JSON dataset reader, DexGraspNet's
``np.load`` and mesh lookup, pandas for Parquet and CSV. The mimics are in
:mod:`tests.datasets.peer_readers`; the reference is the database and the
mesh the planner itself loaded for each object."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import trimesh
from helpers import assert_close

from planner.geometry.solid import load_object
from planner.specs.hands import load_hand
from tests.datasets import peer_readers as peer
from tests.datasets.support import ROUNDED_TOL, export, pose, source_rows

#: (object, hand) pairs of the ``stored_db`` fixture.
PAIRS = [("box", "panda"), ("box", "pr2"), ("capsule", "panda"), ("duck", "panda")]


def planner_mesh(db: Path, name: str) -> trimesh.Trimesh:
    """The mesh the planner loaded for the object when it generated ``stored_db``."""
    if name == "capsule":
        return load_object(str(db.parent / "meshes_in_mm" / "capsule.obj"), scale=0.001).mesh
    return load_object(name, scale=1.5 if name == "duck" else None).mesh


def assert_same_mesh(mesh: object, expected: trimesh.Trimesh) -> None:
    """Vertex for vertex, bit for bit (the OBJ holds 17 significant digits)."""
    assert isinstance(mesh, trimesh.Trimesh), type(mesh)
    assert np.array_equal(mesh.vertices, expected.vertices) and np.array_equal(mesh.faces, expected.faces)


def moved_export(db: Path, fmt: str, tmp_path: Path, *args: str) -> Path:
    """Export into one folder, copy it to another, delete the first; the copy."""
    written = export(db, fmt, tmp_path / "written", *args)
    copy = tmp_path / "elsewhere" / "copy"
    shutil.copytree(written, copy)
    shutil.rmtree(written)
    return copy


def transforms(db: Path, obj: str, hand: str) -> tuple[np.ndarray, np.ndarray]:
    """(N, 4, 4) ACRONYM transforms of the stored grasps in rank order, and
    their (N,) labels (nothing is validated: the force-closure flag)."""
    rows = source_rows(db, obj, f"hand = '{hand}'")
    frame = load_hand(hand).export_frame
    return np.array([pose(r) @ frame for r in rows]).reshape(-1, 4, 4), np.array([r["force_closure"] for r in rows])


def test_acronym_load_grasps_and_load_mesh(stored_db: Path, tmp_path: Path) -> None:
    root = moved_export(stored_db, "acronym", tmp_path)
    files = sorted(root.glob("*.h5"))
    assert [f.name for f in files] == [f"{o}__{h}.h5" for o, h in PAIRS]
    for path in files:
        obj, hand = path.stem.split("__")
        assert peer.check_acronym_file(str(path), str(root)) == []
        T, success = peer.acronym_load_grasps(str(path))
        expected, labels = transforms(stored_db, obj, hand)
        assert_close(T, expected)
        positive, negative = peer.acronym_split(T, success)
        assert_close(positive, expected[labels == 1])
        assert_close(negative, expected[labels == 0])
        assert peer.acronym_mesh_path(str(path), str(root)) == str(root / "meshes" / f"{obj}.obj")
        assert_same_mesh(peer.acronym_load_mesh(str(path), str(root)), planner_mesh(stored_db, obj))


def test_graspgen_reader_per_hand_folder(stored_db: Path, tmp_path: Path) -> None:
    root = moved_export(stored_db, "graspgen", tmp_path)
    hands = sorted(p.name for p in (root / "grasp_data").iterdir())
    assert hands == ["panda", "pr2"]
    for hand in hands:
        grasp_root = root / "grasp_data" / hand
        splits = [peer.graspgen_read_splits(str(root / "splits" / hand / f"{s}.txt")) for s in ("train", "valid")]
        keys = splits[0] + splits[1]
        index = peer.graspgen_index(str(grasp_root))  # the mapping file the export ships
        assert (grasp_root / peer.GRASPGEN_MAPPING).is_file()
        assert sorted(keys) == sorted(index) == sorted(f"meshes/{o}.obj" for o, h in PAIRS if h == hand)
        assert peer.check_graspgen_key_collisions(str(grasp_root)) == {}
        for key in keys:
            obj = Path(key).stem
            json_path = str(grasp_root / index[key])
            assert peer.check_graspgen_file(json_path) == []
            expected, labels = transforms(stored_db, obj, hand)
            positive, negative, mesh = peer.graspgen_load(key, str(grasp_root), str(root))
            assert_close(positive, expected[labels == 1])
            assert_close(negative, expected[labels == 0])
            documented = peer.graspgen_split_documented(json_path)  # grasps[mask], grasps[~mask]
            assert_close(documented[0], expected[labels == 1])
            assert_close(documented[1], expected[labels == 0])
            assert_same_mesh(mesh, planner_mesh(stored_db, obj))
        (grasp_root / peer.GRASPGEN_MAPPING).unlink()  # GraspGen's own scan agrees with the shipped mapping
        assert peer.graspgen_index(str(grasp_root)) == index


def test_an_integer_mask_is_misread_by_the_graspgen_reader(stored_db: Path, tmp_path: Path) -> None:
    """What the test above guards against: 0/1 integers index rows 0 and 1."""
    root = moved_export(stored_db, "graspgen", tmp_path, "--object", "box", "--hand", "panda")
    path = root / "grasp_data" / "panda" / "box.json"
    data = json.loads(path.read_text())
    assert {type(v) for v in data["grasps"]["object_in_gripper"]} == {bool}
    expected, _ = transforms(stored_db, "box", "panda")
    labels = np.arange(len(expected)) % 2  # 0/1 integers, both present whatever the sweep labelled
    data["grasps"]["object_in_gripper"] = labels.tolist()
    path.write_text(json.dumps(data))
    positive, negative = peer.graspgen_split_documented(str(path))
    assert len(positive) == len(negative) == len(labels) != labels.sum()
    assert_close(positive[labels == 1], np.repeat(expected[1:2], labels.sum(), axis=0))
    assert "object_in_gripper is int64, not a JSON boolean list" in peer.check_graspgen_file(str(path))


def test_graspgen_mapping_follows_the_folder(stored_db: Path, tmp_path: Path) -> None:
    """GraspGen writes ``map_uuid_to_path.json`` on first read and trusts it
    ever after; an export into the same folder brings it up to date."""
    out = tmp_path / "dataset"
    export(stored_db, "graspgen", out, "--object", "box", "--hand", "panda")
    grasp_root = str(out / "grasp_data" / "panda")
    (out / "grasp_data" / "panda" / peer.GRASPGEN_MAPPING).unlink()
    assert list(peer.graspgen_index(grasp_root, write_mapping=True)) == ["meshes/box.obj"]
    export(stored_db, "graspgen", out, "--object", "capsule")
    assert sorted(peer.graspgen_index(grasp_root)) == ["meshes/box.obj", "meshes/capsule.obj"]
    assert peer.graspgen_read_splits(str(out / "splits" / "panda" / "train.txt")) + \
        peer.graspgen_read_splits(str(out / "splits" / "panda" / "valid.txt")) != []


def test_dexgraspnet_np_load_and_mesh_lookup(stored_db: Path, tmp_path: Path) -> None:
    root = moved_export(stored_db, "dexgraspnet", tmp_path)
    files = sorted((root / "dataset").glob("*/*.npy"), key=lambda f: (f.stem, f.parent.name))
    assert [(f.stem, f.parent.name) for f in files] == PAIRS
    for path in files:
        obj, hand = path.stem, path.parent.name
        grasps, mesh = peer.dexgraspnet_load(str(path), str(root / "meshdata"))
        rows = source_rows(stored_db, obj, f"hand = '{hand}'")
        assert len(grasps) == len(rows) > 0
        for (scale, qpos), row in zip(grasps, rows):
            assert scale == 1.0
            assert_close(peer.dexgraspnet_wrist_pose(qpos), pose(row), ROUNDED_TOL)
            closed = json.loads(row["closed_joints"])
            assert {k: qpos[k] for k in closed} == closed
        assert_same_mesh(mesh, planner_mesh(stored_db, obj))
        data = np.load(path, allow_pickle=True)
        assert {(d["object_code"], d["mesh_file"]) for d in data} == {(obj, f"meshes/{obj}.obj")}
        assert_same_mesh(trimesh.load(root / data[0]["mesh_file"]), planner_mesh(stored_db, obj))
        # DexGraspNet's hand tools hard-code the Shadow hand: no hand here has its joints
        problems = peer.check_dexgraspnet_validation_inputs(str(path), str(root / "meshdata"))
        assert any(p.startswith("qpos lacks Shadow joints") for p in problems)
        with pytest.raises(KeyError, match="robot0:FFJ3"):
            peer.dexgraspnet_hand_pose(data[0]["qpos"])


def test_parquet_and_csv_with_pandas(stored_db: Path, tmp_path: Path) -> None:
    tables = {fmt: moved_export(stored_db, fmt, tmp_path / fmt) for fmt in ("parquet", "csv")}
    frames = {"parquet": pd.read_parquet(tables["parquet"] / "grasps.parquet"),
              "csv": pd.read_csv(tables["csv"] / "grasps.csv")}
    rows = source_rows(stored_db, "box", "hand = 'panda'")
    for fmt, frame in frames.items():
        assert len(frame) == sum(len(source_rows(stored_db, o, f"hand = '{h}'")) for o, h in PAIRS)
        for column in ("grasp_id", "candidate", "force_closure", "rank", "n_contacts"):
            assert frame[column].dtype == np.int64, (fmt, column)
        for column in ("epsilon", "score", "pose_03", "roll", "object_scale", "validation_success"):
            assert frame[column].dtype == np.float64, (fmt, column)  # nullable integers read as float, NaN
        for column in ("object", "hand", "contacts", "object_file"):
            assert pd.api.types.is_string_dtype(frame[column]), (fmt, column)
        assert frame["validation_success"].isna().all()
        box = frame[(frame["object"] == "box") & (frame["hand"] == "panda")].sort_values("rank")
        poses = box[[f"pose_{i}{j}" for i in range(4) for j in range(4)]].to_numpy().reshape(-1, 4, 4)
        assert_close(poses, [pose(r) for r in rows])
        assert box["epsilon"].tolist() == [r["epsilon"] for r in rows]  # full precision in both
        for (obj, file, scale), _ in frame.groupby(["object", "object_file", "object_scale"]):
            assert file == f"meshes/{obj}.obj" and scale == 1.0
            mesh = trimesh.load(tables[fmt] / file).apply_scale(scale)
            assert_same_mesh(mesh, planner_mesh(stored_db, obj))
