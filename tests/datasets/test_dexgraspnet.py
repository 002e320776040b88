"""DexGraspNet .npy: documented dicts, the wrist in extrinsic xyz Euler angles."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from helpers import assert_close

from tests.datasets.support import ROUNDED_TOL, export, pose, source_rows


def test_dexgraspnet_npy_loads_into_documented_dicts(db: Path, tmp_path: Path) -> None:
    from scipy.spatial.transform import Rotation

    export(db, "dexgraspnet", tmp_path, "--object", "box")
    data = np.load(tmp_path / "dataset" / "panda" / "box.npy", allow_pickle=True)
    rows = source_rows(db, "box")
    assert data.dtype == object and len(data) == len(rows)
    wrist = {"WRJTx", "WRJTy", "WRJTz", "WRJRx", "WRJRy", "WRJRz"}
    for grasp, row in zip(data, rows):
        qpos = grasp["qpos"]
        assert set(qpos) == wrist | {"panda_finger_joint1", "panda_finger_joint2"}
        assert grasp["scale"] == 1.0 and grasp["epsilon"] == row["epsilon"] and grasp["rank"] == row["rank"]
        assert (grasp["object_code"], grasp["mesh_file"]) == ("box", "meshes/box.obj")
        rebuilt = np.eye(4)
        rebuilt[:3, :3] = Rotation.from_euler("xyz", [qpos["WRJRx"], qpos["WRJRy"], qpos["WRJRz"]]).as_matrix()
        rebuilt[:3, 3] = [qpos["WRJTx"], qpos["WRJTy"], qpos["WRJTz"]]
        assert_close(rebuilt, pose(row), ROUNDED_TOL)
        assert qpos["panda_finger_joint1"] == json.loads(row["closed_joints"])["panda_finger_joint1"]
        opened = grasp["qpos_open"]  # the pre-grasp posture: the same wrist, the preshape's open joints
        assert {k: opened[k] for k in wrist} == {k: qpos[k] for k in wrist}
        assert {k: v for k, v in opened.items() if k not in wrist} == json.loads(row["open_joints"])
        assert opened["panda_finger_joint1"] > qpos["panda_finger_joint1"]


def test_the_manifest_lists_the_meshdata_copy_of_each_mesh(db: Path, tmp_path: Path) -> None:
    """DexGraspNet's ObjectModel reads ``meshdata/<object>/coacd/decomposed.obj``: the export writes it, and its
    manifest listed only ``meshes/box.obj`` (a copier going by the manifest left ObjectModel's file behind)."""
    export(db, "dexgraspnet", tmp_path, "--object", "box")
    meshes = json.loads((tmp_path / "export-dexgraspnet.json").read_text())["meshes"]
    assert meshes == ["meshes/box.obj", "meshdata/box/coacd/decomposed.obj"]
    assert all((tmp_path / m).is_file() for m in meshes)


def test_qpos_gives_back_the_pose() -> None:
    from scipy.spatial.transform import Rotation

    from planner.datasets.dexgraspnet import WRIST, pose_from_qpos, wrist

    poses = np.tile(np.eye(4), (3, 1, 1))
    angles = [[0.1, 0.2, 0.3], [2.0, -1.0, 0.5], [0.0, np.pi / 2, 0.0]]  # the last at gimbal lock
    poses[:, :3, :3] = Rotation.from_euler("xyz", angles).as_matrix()
    poses[:, :3, 3] = [[0.1, 0.0, 0.2], [0.0, 0.3, 0.0], [-0.1, 0.0, 0.05]]
    for p, q in zip(poses, wrist(poses)):
        assert_close(pose_from_qpos(dict(zip(WRIST, q))), p, 1e-9)
