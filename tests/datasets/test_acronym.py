"""ACRONYM HDF5: the layout ACRONYM's own loaders read, and its labels."""

from __future__ import annotations

import json
import re
from pathlib import Path

import h5py
import numpy as np
import pytest
import trimesh
from helpers import assert_close

from planner.datasets import acronym
from planner.datasets.acronym import CONFIGURATION_DOC, gripper_configuration
from planner.geometry.solid import load_object
from planner.specs.hands import hand_names, load_hand
from tests.datasets.support import export, source_rows

#: Fingertip points of a closed Panda lie this close to the surface [m]
#: (PyBullet's margins are corrected to ~0.3 mm; 2 mm leaves room).
SURFACE_TOL = 0.002
PANDA_PAD_Z = 0.1034  # ACRONYM's Panda: finger pads at z = 10.34 cm


def fingertips(transforms: np.ndarray, width: np.ndarray, axis: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """ACRONYM's Panda drawn at the transforms: (N, 3) pad centres of both fingers."""
    offset = np.zeros((len(width), 4))
    offset[:, axis] = width / 2
    offset[:, 2], offset[:, 3] = PANDA_PAD_Z, 1.0
    flip = offset * [-1, -1, 1, 1]
    return np.einsum("nij,nj->ni", transforms, offset)[:, :3], np.einsum("nij,nj->ni", transforms, flip)[:, :3]


def grips(mesh: trimesh.Trimesh, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N,) both pads on the surface, the object between them."""
    n = len(a)
    dist = trimesh.proximity.signed_distance(mesh, np.vstack([a, b, (a + b) / 2]))  # > 0 inside
    on_surface = (np.abs(dist[:n]) < SURFACE_TOL) & (np.abs(dist[n:2 * n]) < SURFACE_TOL)
    return on_surface & (dist[2 * n:] > 0)


def test_acronym_layout_read_by_plain_h5py(db: Path, tmp_path: Path) -> None:
    path = export(db, "acronym", tmp_path, "--object", "box") / "box__panda.h5"
    with h5py.File(path, "r") as f:  # what ACRONYM's own loaders read
        transforms = np.array(f["grasps/transforms"])
        success = np.array(f["grasps/qualities/flex/object_in_gripper"])
        mesh_file = f["object/file"][()].decode("utf-8")
        scale, gripper = f["object/scale"][()], f["gripper/type"][()].decode()
        width, fc = f["grasps/width"][()], f["grasps/qualities/force_closure"][()]
        label_source = f["grasps/qualities/flex/object_in_gripper"].attrs["label_source"]
        label_from = [v.decode() if isinstance(v, bytes) else v for v in f["grasps/qualities/label_from"][()]]
        assert f["gripper/configuration"].shape == (1,) and f["object/inertia"].shape == (3, 3)
        assert_close(f["grasps/poses_hand_frame"][()] @ f["grasps/export_frame"][()], transforms)
    rows = source_rows(db, "box")
    assert transforms.shape == (len(rows), 4, 4) and transforms.dtype == np.float64
    assert success.dtype == np.int64 and set(success) <= {0, 1}
    assert (mesh_file, scale, gripper) == ("meshes/box.obj", 1.0, "panda")
    # labels: the trial where validated (the best grasp was 'dropped'), else (no p_hold model in the tests)
    # the force-closure flag, each row saying which
    assert label_source == "mixed" and success[0] == 0 and success[1] == 1
    assert list(success[2:]) == [r["force_closure"] for r in rows[2:]]
    assert list(label_from[:2]) == ["trial", "trial"] and set(label_from[2:]) == {"force_closure"}
    mesh = load_object("box").mesh
    closure = fc == 1
    a, b = fingertips(transforms[closure], width[closure])
    assert closure.sum() > 0 and grips(mesh, a, b).all()
    a, b = fingertips(transforms[closure], width[closure], axis=1)  # fingers along y: not ACRONYM's frame
    assert not grips(mesh, a, b).all()


def test_a_small_file_is_not_padded_to_whole_chunks(db: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A chunk is stored whole: 5 grasps in 1,024-row chunks took ~1.6 MB (78 datasets). A file's chunks are at
    most CHUNK_ROWS rows and at most its first batch's."""
    small = export(db, "acronym", tmp_path / "small", "--object", "box", "--top", "5") / "box__panda.h5"
    monkeypatch.setattr(acronym, "CHUNK_ROWS", 4)
    capped = export(db, "acronym", tmp_path / "capped", "--object", "box", "--top", "5") / "box__panda.h5"
    for path, rows in ((small, 5), (capped, 4)):
        with h5py.File(path, "r") as f:
            names: list[str] = []
            f["grasps"].visit(names.append)
            chunks = {f["grasps"][n].chunks[0] for n in names if isinstance(f["grasps"][n], h5py.Dataset)
                      and f["grasps"][n].chunks}
            assert chunks == {rows} and f["grasps/transforms"].shape == (5, 4, 4)
    assert small.stat().st_size < 400_000


def test_label_source_simulation_when_every_grasp_was_validated(db: Path, tmp_path: Path) -> None:
    path = export(db, "acronym", tmp_path, "--object", "box", "--top", "2") / "box__panda.h5"
    with h5py.File(path, "r") as f:
        labels = f["grasps/qualities/flex/object_in_gripper"]
        assert labels.attrs["label_source"] == "trial" and list(labels[()]) == [0, 1]
        assert [v.decode() if isinstance(v, bytes) else v for v in f["grasps/qualities/label_from"][()]] == \
            ["trial", "trial"]
        assert list(f["grasps/qualities/simulated_success"][()]) == [0, 1]
        assert_close(f["grasps/qualities/flex/object_motion_during_shaking_angular"][()], [0.02, 0.02])
        assert_close(f["grasps/qualities/robust_epsilon_mean"][()], [0.05, 0.05])


def test_object_scale_turns_the_mesh_file_into_the_object() -> None:
    """What ACRONYM readers do with object/file and object/scale; the duck's
    URDF scales its mesh file by 0.05 on top of the registry's scale."""
    duck = load_object("duck")
    scale = duck.file_scale
    raw = trimesh.load(duck.source_file, force="mesh", process=False)
    assert scale == pytest.approx(0.05)
    assert_close(raw.extents * scale, duck.mesh.extents)


def test_the_reader_refuses_what_is_not_a_rigid_transform(tmp_path: Path) -> None:
    from planner.datasets import acronym
    from planner.errors import InputError
    from planner.specs.hands import load_hand

    path = tmp_path / "skewed.h5"
    transforms = np.tile(np.eye(4), (3, 1, 1))
    transforms[2, 0, 0] = 2.0
    with h5py.File(path, "w") as f:
        f["gripper/type"], f["grasps/transforms"] = "panda", transforms
    header = acronym.read_header(path)
    assert (header.gripper, header.extras, header.scale) == ("panda", False, None)
    with pytest.raises(InputError, match="row 2 is not a rigid transform"):
        acronym.read_poses(path, load_hand("panda"))
    with h5py.File(tmp_path / "empty.h5", "w") as f:
        f["object/file"] = "x.obj"
    with pytest.raises(InputError, match="no 'grasps/transforms' dataset; not an ACRONYM grasp file"):
        acronym.read_header(tmp_path / "empty.h5")


def documented_configurations() -> dict[str, tuple[list[str], list[float]]]:
    """hand -> (joints, values) of the gripper/configuration table."""
    rows = {}
    for line in CONFIGURATION_DOC.splitlines()[2:]:
        hand, joints, values, _ = (cell.strip() for cell in line.strip("|").split("|"))
        rows[hand] = (re.findall(r"`([a-z_0-9]+)`", joints), json.loads(values.strip("`")))
    return rows


def test_gripper_configuration_is_acronyms_for_the_panda_and_documented_for_every_hand() -> None:
    documented = documented_configurations()
    assert sorted(documented) == hand_names()
    for hand, (joints, values) in documented.items():
        names, configuration = gripper_configuration(load_hand(hand))
        assert (names, configuration.tolist()) == (joints, values), hand
    assert documented["panda"] == (["panda_finger_joint1"], [0.04])  # ACRONYM's own Panda files
    readme = (Path(__file__).parents[2] / "README.md").read_text()
    assert CONFIGURATION_DOC in readme



def _labelled(db: Path, tmp_path: Path, choice: str) -> tuple[list, set, list, list]:
    path = export(db, "acronym", tmp_path, "--object", "box", "--label", choice) / "box__panda.h5"
    with h5py.File(path, "r") as f:
        labels = f["grasps/qualities/flex/object_in_gripper"]
        assert labels.attrs["label_source"] == choice
        label_from = {v.decode() if isinstance(v, bytes) else v for v in f["grasps/qualities/label_from"][()]}
        return (list(labels[()]), label_from, list(f["grasps/qualities/force_closure"][()]),
                list(f["grasps/qualities/simulated_success"][()]))


def test_export_label_trial_keeps_only_validated_grasps(db: Path, tmp_path: Path) -> None:
    labels, label_from, _, simulated = _labelled(db, tmp_path, "trial")
    assert labels == simulated == [0, 1] and label_from == {"trial"}


def test_export_label_force_closure_writes_the_flag(db: Path, tmp_path: Path) -> None:
    labels, label_from, closure, _ = _labelled(db, tmp_path, "force_closure")
    assert labels == closure and len(closure) > 2 and label_from == {"force_closure"}


def test_labels_pick_the_best_source_per_grasp() -> None:
    from planner.datasets.labels import P_HOLD_SUCCESS, labels

    # the 6th and 7th: held in PyBullet but dropped in MuJoCo (dropped), and tried in MuJoCo only (held);
    # the last two: p_hold updated by their verdicts (0.3: dropped although the trial held; 0.8: held)
    columns = {"validation_success": np.array([1, 0, -1, -1, -1, 1, -1, 1, -1]),
               "mujoco_success": np.array([-1, -1, -1, -1, -1, 0, 1, -1, 0]),
               "p_hold": np.array([0.1, 0.9, 0.7, 0.2, np.nan, 0.9, 0.1, 0.4, 0.95]),
               "p_hold_trial": np.array([np.nan] * 7 + [0.3, 0.8]),
               "force_closure": np.array([0, 1, 0, 1, 1, 1, 0, 1, 1]),
               "file_label_success": np.full(9, -1)}
    value, source = labels(columns, "best")
    assert source == ["trial", "trial", "p_hold", "p_hold", "force_closure", "trial", "trial", "p_hold_trial",
                      "p_hold_trial"]
    assert list(value) == [1, 0, int(0.7 >= P_HOLD_SUCCESS), int(0.2 >= P_HOLD_SUCCESS), 1, 0, 1, 0, 1]
    # an imported file's own label comes first where a file gave one (FleX's, a user's outcomes)
    given = {**columns, "file_label_success": np.array([0, -1, 1, -1, -1, -1, -1, 1, -1])}
    value, source = labels(given, "best")
    assert source[0] == source[2] == source[7] == "file_label" and source[1] == "trial"
    assert list(value[[0, 2, 7]]) == [0, 1, 1]
    value, source = labels(given, "file_label")
    assert list(value[[0, 2, 7]]) == [0, 1, 1] and set(source) == {"file_label"}
    value, source = labels(columns, "trial")
    assert list(value[-2:]) == [1, 0] and set(source) == {"trial"}
    value, source = labels(columns, "force_closure")
    assert list(value) == [0, 1, 0, 1, 1, 1, 0, 1, 1] and set(source) == {"force_closure"}


def test_labels_that_are_not_0_or_1_are_named(tmp_path: Path) -> None:
    from planner.datasets.acronym import read_labels
    from planner.errors import InputError

    path = tmp_path / "labels.h5"
    with h5py.File(path, "w") as f:
        f["grasps/transforms"] = np.tile(np.eye(4), (4, 1, 1))
        f["grasps/qualities/flex/object_in_gripper"] = np.array([0.0, 1.0, 2.0, np.nan])
    with pytest.raises(InputError, match=r"must hold 0/1 labels; 2 of 4 are not \(2, nan\)"):
        read_labels(path)
    with h5py.File(path, "r+") as f:
        del f["grasps/qualities/flex/object_in_gripper"]
        f["grasps/qualities/flex/object_in_gripper"] = np.array([0, 1, 1])
    with pytest.raises(InputError, match=r"one 0/1 label per grasp \(4\), got 3 values"):
        read_labels(path)


def test_labels_as_text_or_of_another_shape_are_named_and_a_column_is_read(tmp_path: Path) -> None:
    """b'yes'/b'no' labels and an (N, 2) array raised numpy's errors (exit 1 from grasp calibrate)."""
    from planner.datasets.acronym import read_labels
    from planner.errors import InputError

    path = tmp_path / "labels.h5"
    key = "grasps/qualities/flex/object_in_gripper"
    with h5py.File(path, "w") as f:
        f["grasps/transforms"] = np.tile(np.eye(4), (3, 1, 1))
        f[key] = np.array([b"yes", b"no", b"yes"])
    with pytest.raises(InputError, match=rf"labels.h5: {key} holds text values \(b'yes', b'no', ...\); it must"):
        read_labels(path)
    with h5py.File(path, "r+") as f:
        del f[key]
        f[key] = np.zeros((3, 2))
    with pytest.raises(InputError, match=rf"labels.h5: {key} has shape \(3, 2\); it must hold one 0/1 label per"):
        read_labels(path)
    with h5py.File(path, "r+") as f:
        del f[key]
        f[key] = np.array([[1], [0], [1]], np.int64)  # one column: unambiguous
    assert read_labels(path).tolist() == [1.0, 0.0, 1.0]
